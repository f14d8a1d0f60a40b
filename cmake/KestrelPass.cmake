# kestrel_add_pass(<name> SOURCES <impl sources...> PLUGIN <plugin.cpp> [LIBS <libs...>])
#
# Builds a pass folder into two targets:
#   kestrel_pass_<name>    static library with the pass implementation (tests link it)
#   kestrel_plugin_<name>  the plugin module kestrel_<name>.so, loaded at start by the engine
function(kestrel_add_pass name)
  cmake_parse_arguments(P "" "" "SOURCES;PLUGIN;LIBS" ${ARGN})
  add_library(kestrel_pass_${name} STATIC ${P_SOURCES})
  set_target_properties(kestrel_pass_${name} PROPERTIES POSITION_INDEPENDENT_CODE ON)
  target_include_directories(kestrel_pass_${name} PUBLIC ${CMAKE_CURRENT_SOURCE_DIR})
  target_link_libraries(kestrel_pass_${name} PUBLIC kestrel::framework ${P_LIBS})

  add_library(kestrel_plugin_${name} MODULE ${P_PLUGIN})
  target_link_libraries(kestrel_plugin_${name} PRIVATE kestrel_pass_${name})
  set_target_properties(kestrel_plugin_${name} PROPERTIES
    OUTPUT_NAME kestrel_${name}
    PREFIX ""
    LIBRARY_OUTPUT_DIRECTORY ${KESTREL_PLUGIN_BUILD_DIR}
    CXX_VISIBILITY_PRESET hidden
    INSTALL_RPATH "$ORIGIN/../..")
  install(TARGETS kestrel_plugin_${name} LIBRARY DESTINATION ${KESTREL_PLUGIN_INSTALL_DIR})
  set_property(GLOBAL APPEND PROPERTY KESTREL_PLUGINS kestrel_plugin_${name})
endfunction()
