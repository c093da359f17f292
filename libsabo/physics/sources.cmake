# Sources of libsabo/physics.
target_sources(sabo_core PRIVATE)
