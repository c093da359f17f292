# Sources of libsabo/geometry.
target_sources(sabo_core PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/covering_boxes.cpp
  ${CMAKE_CURRENT_LIST_DIR}/hexahedron.cpp
  ${CMAKE_CURRENT_LIST_DIR}/node_welder.cpp
  ${CMAKE_CURRENT_LIST_DIR}/primitives.cpp
  ${CMAKE_CURRENT_LIST_DIR}/sphere_fill.cpp
  ${CMAKE_CURRENT_LIST_DIR}/sphere_sampling.cpp
  ${CMAKE_CURRENT_LIST_DIR}/surface_mesh.cpp
  ${CMAKE_CURRENT_LIST_DIR}/surface_patch.cpp
  ${CMAKE_CURRENT_LIST_DIR}/surface_sampling.cpp
)
