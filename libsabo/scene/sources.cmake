# Sources of libsabo/scene.
target_sources(sabo_core PRIVATE)
target_sources(sabo_core PRIVATE ${CMAKE_CURRENT_LIST_DIR}/scene.cpp)
