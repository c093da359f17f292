# Sources of libsabo/contact: the particle-surface penalty contact (paper eqs. 3-6) that the coupler
# (DEM-FEM, penalty SPH-FEM) and the fem_solver (structure against structure) share.
target_sources(sabo_core PRIVATE ${CMAKE_CURRENT_LIST_DIR}/sphere_triangle.cpp ${CMAKE_CURRENT_LIST_DIR}/surface_contact.cpp
                                 ${CMAKE_CURRENT_LIST_DIR}/surface_contact_history.cpp)
