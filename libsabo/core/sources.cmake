# Sources of libsabo/core.
target_sources(sabo_core PRIVATE)
