# Sources of libsabo/protocol.
target_sources(sabo_core PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/message_compare.cpp
  ${CMAKE_CURRENT_LIST_DIR}/security.cpp
  ${CMAKE_CURRENT_LIST_DIR}/socket.cpp
  ${CMAKE_CURRENT_LIST_DIR}/solver_link.cpp
  ${CMAKE_CURRENT_LIST_DIR}/surface_codec.cpp
  ${CMAKE_CURRENT_LIST_DIR}/walls_ahead.cpp
  ${CMAKE_CURRENT_LIST_DIR}/wire.cpp
)
