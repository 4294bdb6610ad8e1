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
