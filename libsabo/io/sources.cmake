# Sources of libsabo/io.
target_sources(sabo_core PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/checkpoint.cpp
  ${CMAKE_CURRENT_LIST_DIR}/gmsh.cpp
  ${CMAKE_CURRENT_LIST_DIR}/gmsh_groups.cpp
  ${CMAKE_CURRENT_LIST_DIR}/hdf5.cpp
  ${CMAKE_CURRENT_LIST_DIR}/pairs_csv.cpp
  ${CMAKE_CURRENT_LIST_DIR}/raster.cpp
  ${CMAKE_CURRENT_LIST_DIR}/stl.cpp
  ${CMAKE_CURRENT_LIST_DIR}/traffic.cpp
  ${CMAKE_CURRENT_LIST_DIR}/traffic_reader.cpp
  ${CMAKE_CURRENT_LIST_DIR}/vtk.cpp
)
