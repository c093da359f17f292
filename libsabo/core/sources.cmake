target_sources(sabo_core PRIVATE ${CMAKE_CURRENT_LIST_DIR}/signals.cpp ${CMAKE_CURRENT_LIST_DIR}/log.cpp)
