# Helpers shared by every module's CMakeLists.txt.

# Warnings for the project's own code only (never for third-party headers).
add_library(cnc_build_flags INTERFACE)
target_compile_options(cnc_build_flags INTERFACE
  -Wall -Wextra -Werror -Wno-missing-field-initializers)
if(CNC_SANITIZE)
  target_compile_options(cnc_build_flags INTERFACE -fsanitize=address,undefined -fno-omit-frame-pointer)
  target_link_options(cnc_build_flags INTERFACE -fsanitize=address,undefined)
endif()

# cnc_subdirectories(dir...): add each folder that has a CMakeLists.txt.
function(cnc_subdirectories)
  foreach(dir IN LISTS ARGN)
    if(EXISTS ${CMAKE_CURRENT_SOURCE_DIR}/${dir}/CMakeLists.txt)
      add_subdirectory(${dir})
    endif()
  endforeach()
endfunction()

# cnc_library(<name> SOURCES ... [PUBLIC_DEPS ...] [PRIVATE_DEPS ...])
# Creates static library cnc_<name>; the repository root is the include root,
# so headers are included as "core/hal/pin.hpp".
function(cnc_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(cnc_${name} STATIC ${ARG_SOURCES})
  target_include_directories(cnc_${name} PUBLIC ${PROJECT_SOURCE_DIR})
  target_link_libraries(cnc_${name} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE cnc_build_flags ${ARG_PRIVATE_DEPS})
endfunction()

# cnc_executable(<name> SOURCES ... [DEPS ...]): a program in build/bin.
function(cnc_executable name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE cnc_build_flags ${ARG_DEPS})
endfunction()

# cnc_gtest(<name> SOURCES ... [DEPS ...] [LABELS ...] [TIMEOUT s] [ENV ...])
# A GoogleTest program; every TEST becomes one CTest test carrying LABELS
# (default: unit). Labels: unit, vm, netns, gui, slow.
function(cnc_gtest name)
  cmake_parse_arguments(ARG "" "TIMEOUT" "SOURCES;DEPS;LABELS;ENV" ${ARGN})
  if(NOT ARG_LABELS)
    set(ARG_LABELS unit)
  endif()
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 120)
  endif()
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE cnc_build_flags cnc_testing ${ARG_DEPS} GTest::gtest GTest::gmock)
  gtest_discover_tests(${name}
    DISCOVERY_MODE PRE_TEST
    PROPERTIES LABELS "${ARG_LABELS}" TIMEOUT ${ARG_TIMEOUT} ENVIRONMENT "${ARG_ENV}")
endfunction()

# cnc_check_product_links(): the simulators (sim/, targets cnc_sim*) are not
# part of the product. Fails the configuration when a product target links
# one of them, directly or through another library: every cnc_* library
# that is not a simulator, and the programs a machine runs (cnc, halcmd,
# cnc-hmi). cncd is the one exception: it takes the simulators as its
# build-time plug-in (core/daemon/plugins.hpp), never through a library.
function(_cnc_sim_links target out)
  set(seen "${ARGN}")
  set(found "")
  foreach(prop LINK_LIBRARIES INTERFACE_LINK_LIBRARIES)
    get_target_property(libs ${target} ${prop})
    if(NOT libs)
      continue()
    endif()
    foreach(lib IN LISTS libs)
      if(NOT TARGET ${lib} OR lib IN_LIST seen)
        continue()
      endif()
      list(APPEND seen ${lib})
      if(lib MATCHES "^cnc_sim")
        list(APPEND found ${lib})
      else()
        _cnc_sim_links(${lib} sub ${seen})
        list(APPEND found ${sub})
      endif()
    endforeach()
  endforeach()
  set(${out} ${found} PARENT_SCOPE)
endfunction()

function(cnc_check_product_links)
  set(products cnc halcmd cnc-hmi)
  foreach(dir IN ITEMS core/util core/ini core/rt core/hal core/ipc core/tooltable kinematics core/tp core/interp
                       core/motion cia402 fieldbus/can fieldbus/canopen fieldbus/ethercat comp core/io core/task
                       core/daemon core/cli hmi)
    if(EXISTS ${PROJECT_SOURCE_DIR}/${dir}/CMakeLists.txt)
      get_directory_property(targets DIRECTORY ${PROJECT_SOURCE_DIR}/${dir} BUILDSYSTEM_TARGETS)
      list(APPEND products ${targets})
    endif()
  endforeach()
  list(REMOVE_ITEM products cncd)
  foreach(t IN LISTS products)
    if(NOT TARGET ${t} OR t MATCHES "^cnc_sim")
      continue()
    endif()
    _cnc_sim_links(${t} sims)
    if(sims)
      list(REMOVE_DUPLICATES sims)
      message(FATAL_ERROR "${t} is part of the product but links the simulators (${sims}): "
                          "product targets never link sim/ (docs/architecture.md, \"Simulators\")")
    endif()
  endforeach()
endfunction()
