# Sources of libsabo/io.
target_sources(sabo_core PRIVATE)
