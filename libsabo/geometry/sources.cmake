# Sources of libsabo/geometry.
target_sources(sabo_core PRIVATE)
