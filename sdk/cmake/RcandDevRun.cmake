# rcand_add_dev_run(<plugin target> FRAGMENT <fragment.json> [BASE <robot.json>])
#
# Runs the plugin under development on a simulated robot: `cmake --build build --target dev-run` (builds the plugin
# first), or `build/dev-run [rcand arguments...]` (e.g. --port 0). Either starts rcand with
#   --config build/dev/robot.rcan.yaml    BASE (default: the SDK's simulated rover, share/rcand-sdk/dev) with FRAGMENT
#                                         merged in: mappings key by key, lists appended to, other values replaced
#   --plugin-path <the plugin's output directory> --plugin-path <each of RCAND_DEV_PLUGIN_PATHS>
# The fragment is what enables the plugin: its capability in rcan_protocol.capabilities, its driver in drivers, its
# settings under runtime.capabilities. Both files are JSON (which is YAML, so rcand reads the result as it is):
# CMake can merge JSON, and the SDK needs no other tool. The merged config is rewritten at configure time, which
# an edit of either file triggers.
#
# Cache variables: RCAND_EXECUTABLE (the rcand to run; the environment variable RCAND overrides it per run) and
# RCAND_DEV_PLUGIN_PATHS (where the robot's other plugins are: the sim drive, teleop and chat of rcand-plugins-core).
# The robot's state (the e-stop latch) is kept in build/dev/state. Development credentials only: the pre-shared
# tokens rcand-dev-owner, rcand-dev-user and rcand-dev-guest (sdk/README.md).
set(_RCAND_DEV_RUN_CMAKE_DIR ${CMAKE_CURRENT_LIST_DIR} CACHE INTERNAL "where RcandDevRun.cmake is")

# JSON text of a value string(JSON GET) returned with its TYPE: CMake hands back scalars decoded (strings unquoted,
# booleans ON/OFF, null empty), and string(JSON SET) wants JSON text.
function(_rcand_json_text out type value)
  if(type STREQUAL "STRING")
    string(REPLACE "\\" "\\\\" value "${value}")
    string(REPLACE "\"" "\\\"" value "${value}")
    string(REPLACE "\n" "\\n" value "${value}")
    string(REPLACE "\r" "\\r" value "${value}")
    string(REPLACE "\t" "\\t" value "${value}")
    set(value "\"${value}\"")
  elseif(type STREQUAL "BOOLEAN")
    if(value)
      set(value true)
    else()
      set(value false)
    endif()
  elseif(type STREQUAL "NULL")
    set(value null)
  endif()
  set(${out} "${value}" PARENT_SCOPE)
endfunction()

# <out> = <base> with <overlay> merged in: objects key by key (recursively), arrays appended, anything else replaced.
function(_rcand_json_merge out base overlay)
  string(JSON _overlay_type TYPE "${overlay}")
  string(JSON _base_type ERROR_VARIABLE _no_base TYPE "${base}")
  set(_result "${base}")
  if(_overlay_type STREQUAL "OBJECT" AND _base_type STREQUAL "OBJECT")
    string(JSON _count LENGTH "${overlay}")
    if(_count GREATER 0)
      math(EXPR _last "${_count} - 1")
      foreach(_i RANGE ${_last})
        string(JSON _key MEMBER "${overlay}" ${_i})
        string(JSON _type TYPE "${overlay}" "${_key}")
        string(JSON _value GET "${overlay}" "${_key}")
        _rcand_json_text(_value ${_type} "${_value}")
        string(JSON _existing ERROR_VARIABLE _missing GET "${_result}" "${_key}")
        if(NOT _missing AND _type MATCHES "^(OBJECT|ARRAY)$")
          _rcand_json_merge(_value "${_existing}" "${_value}")
        endif()
        string(JSON _result SET "${_result}" "${_key}" "${_value}")
      endforeach()
    endif()
  elseif(_overlay_type STREQUAL "ARRAY" AND _base_type STREQUAL "ARRAY")
    string(JSON _count LENGTH "${overlay}")
    if(_count GREATER 0)
      math(EXPR _last "${_count} - 1")
      foreach(_i RANGE ${_last})
        string(JSON _type TYPE "${overlay}" ${_i})
        string(JSON _value GET "${overlay}" ${_i})
        _rcand_json_text(_value ${_type} "${_value}")
        string(JSON _end LENGTH "${_result}")
        string(JSON _result SET "${_result}" ${_end} "${_value}")
      endforeach()
    endif()
  else()
    set(_result "${overlay}")
  endif()
  set(${out} "${_result}" PARENT_SCOPE)
endfunction()

# A word for a POSIX sh script, single-quoted.
function(_rcand_sh_quote out text)
  string(REPLACE "'" "'\\''" text "${text}")
  set(${out} "'${text}'" PARENT_SCOPE)
endfunction()

function(rcand_add_dev_run target)
  cmake_parse_arguments(DEV "" "FRAGMENT;BASE" "" ${ARGN})
  if(NOT DEV_FRAGMENT)
    message(FATAL_ERROR "rcand_add_dev_run(${target}): FRAGMENT is required (the config that enables the plugin)")
  endif()
  if(NOT DEV_BASE)
    set(DEV_BASE ${RCAND_SDK_DEV_CONFIG})
  endif()
  get_filename_component(DEV_FRAGMENT ${DEV_FRAGMENT} ABSOLUTE)
  file(READ ${DEV_BASE} _base)
  file(READ ${DEV_FRAGMENT} _fragment)
  string(JSON _type ERROR_VARIABLE _error TYPE "${_fragment}")
  if(_error OR NOT _type STREQUAL "OBJECT")
    message(FATAL_ERROR "${DEV_FRAGMENT}: not a JSON object (${_error})")
  endif()
  _rcand_json_merge(_config "${_base}" "${_fragment}")
  set(_dev_dir ${CMAKE_BINARY_DIR}/dev)
  file(CONFIGURE OUTPUT ${_dev_dir}/robot.rcan.yaml CONTENT "${_config}\n")
  set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS ${DEV_BASE} ${DEV_FRAGMENT})

  find_program(RCAND_EXECUTABLE rcand PATHS /usr/sbin /usr/local/sbin DOC "The rcand that dev-run starts")
  set(_default_paths /usr/local/lib/rcand/plugins)
  if(RCAND_PLUGIN_INSTALL_DIR)
    list(APPEND _default_paths ${RCAND_PLUGIN_INSTALL_DIR})
  endif()
  set(RCAND_DEV_PLUGIN_PATHS "${_default_paths}" CACHE STRING "dev-run: the robot's other plugin directories")

  _rcand_sh_quote(_rcand "${RCAND_EXECUTABLE}")
  _rcand_sh_quote(_config_file "${_dev_dir}/robot.rcan.yaml")
  set(_paths "--plugin-path '$<TARGET_FILE_DIR:${target}>'")
  foreach(_path IN LISTS RCAND_DEV_PLUGIN_PATHS)
    _rcand_sh_quote(_path "${_path}")
    string(APPEND _paths " --plugin-path ${_path}")
  endforeach()
  file(GENERATE OUTPUT ${CMAKE_BINARY_DIR}/dev-run CONTENT "#!/bin/sh
# Generated by rcand_add_dev_run (RcandDevRun.cmake): rcand on the simulated robot with ${target} under development.
# Arguments go to rcand (--port 0, --strict); RCAND=/path/to/rcand runs another rcand. Ctrl-C stops it (e-stop first).
rcand=\${RCAND:-${_rcand}}
if [ ! -x \"\$rcand\" ]; then
  echo \"dev-run: no rcand at '\$rcand': install the rcand package, or configure with -DRCAND_EXECUTABLE=<path>\" >&2
  exit 1
fi
exec \"\$rcand\" --config ${_config_file} ${_paths} \"\$@\"
" FILE_PERMISSIONS OWNER_READ OWNER_WRITE OWNER_EXECUTE GROUP_READ GROUP_EXECUTE WORLD_READ WORLD_EXECUTE)  # after CONTENT: CMake 3.25 aborts when it comes first
  add_custom_target(dev-run COMMAND ${CMAKE_BINARY_DIR}/dev-run DEPENDS ${target} USES_TERMINAL VERBATIM
    COMMENT "rcand on the simulated robot with ${target} (Ctrl-C stops it)")
endfunction()
