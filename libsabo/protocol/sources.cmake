# Sources of libsabo/protocol.
target_sources(sabo_core PRIVATE)
