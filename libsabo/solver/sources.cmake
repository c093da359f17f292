target_sources(sabo_core PRIVATE ${CMAKE_CURRENT_LIST_DIR}/driver.cpp)
