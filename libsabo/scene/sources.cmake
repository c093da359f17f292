# Sources of libsabo/scene.
target_sources(sabo_core PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/estimate.cpp
  ${CMAKE_CURRENT_LIST_DIR}/scene.cpp
  ${CMAKE_CURRENT_LIST_DIR}/schema.cpp
  ${CMAKE_CURRENT_LIST_DIR}/suggest.cpp
  ${CMAKE_CURRENT_LIST_DIR}/loader.cpp
  ${CMAKE_CURRENT_LIST_DIR}/plan.cpp
  ${CMAKE_CURRENT_LIST_DIR}/sensor_patch.cpp
  ${CMAKE_CURRENT_LIST_DIR}/warnings.cpp
  ${CMAKE_CURRENT_LIST_DIR}/detail/reader.cpp
  ${CMAKE_CURRENT_LIST_DIR}/detail/text.cpp
  ${CMAKE_CURRENT_LIST_DIR}/sections/checks.cpp
  ${CMAKE_CURRENT_LIST_DIR}/sections/contact.cpp
  ${CMAKE_CURRENT_LIST_DIR}/sections/fluids.cpp
  ${CMAKE_CURRENT_LIST_DIR}/sections/inflows.cpp
  ${CMAKE_CURRENT_LIST_DIR}/sections/instruments.cpp
  ${CMAKE_CURRENT_LIST_DIR}/sections/interactions.cpp
  ${CMAKE_CURRENT_LIST_DIR}/sections/materials.cpp
  ${CMAKE_CURRENT_LIST_DIR}/sections/particles.cpp
  ${CMAKE_CURRENT_LIST_DIR}/sections/run.cpp
  ${CMAKE_CURRENT_LIST_DIR}/sections/structures.cpp)
