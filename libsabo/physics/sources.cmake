# Sources of libsabo/physics.
target_sources(sabo_core PRIVATE ${CMAKE_CURRENT_LIST_DIR}/contact_law.cpp ${CMAKE_CURRENT_LIST_DIR}/cell_list.cpp)
target_sources(sabo_core PRIVATE ${CMAKE_CURRENT_LIST_DIR}/hertz_mindlin.cpp)
