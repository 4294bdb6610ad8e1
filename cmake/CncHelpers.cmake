# Helpers shared by every module's CMakeLists.txt.

# Warnings for the project's own code only (never for third-party headers).
add_library(cnc_build_flags INTERFACE)
target_compile_options(cnc_build_flags INTERFACE
  -Wall -Wextra -Werror -Wno-missing-field-initializers)
if(CNC_FUZZ)
  # clang's -Wall has warnings gcc's lacks (an unused private field in the
  # simulators); the gcc build enforces the warnings, the fuzz build hunts crashes.
  target_compile_options(cnc_build_flags INTERFACE -Wno-unused-private-field)
endif()
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

# cnc_gtest(<name> SOURCES ... [DEPS ...] [LABELS ...] [TIMEOUT s] [ENV ...] [RESOURCE_LOCK name])
# A GoogleTest program; every TEST becomes one CTest test carrying LABELS
# (default: unit). Labels: unit, vm, netns, gui, slow. RESOURCE_LOCK: tests
# holding the same lock never run at once (heavy ones that run cncd).
function(cnc_gtest name)
  cmake_parse_arguments(ARG "RUN_SERIAL" "TIMEOUT;RESOURCE_LOCK" "SOURCES;DEPS;LABELS;ENV" ${ARGN})
  if(NOT ARG_LABELS)
    set(ARG_LABELS unit)
  endif()
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 120)
  endif()
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE cnc_build_flags cnc_testing ${ARG_DEPS} GTest::gtest GTest::gmock)
  set(lock)
  if(ARG_RESOURCE_LOCK)
    set(lock RESOURCE_LOCK ${ARG_RESOURCE_LOCK})
  endif()
  # RUN_SERIAL: nothing else runs beside it (long end-to-end runs whose
  # simulated servo thread stalls when the 2-core host is also busy).
  if(ARG_RUN_SERIAL)
    list(APPEND lock RUN_SERIAL TRUE)
  endif()
  gtest_discover_tests(${name}
    DISCOVERY_MODE PRE_TEST
    PROPERTIES LABELS "${ARG_LABELS}" TIMEOUT ${ARG_TIMEOUT} ENVIRONMENT "${ARG_ENV}" ${lock})
endfunction()

# cnc_fuzz_target(<name> SOURCES ... [DEPS ...] [SEEDS files-or-folders ...] [DICT file])
# A parser's fuzz harness (a LLVMFuzzerTestOneInput in SOURCES) built as:
#  - <name>_fuzz_replay, always: runs the seeds, the regression corpus
#    (corpus/<name>/ next to the harness: inputs that once crashed or hung)
#    and fixed variants of each; CTest test fuzz.<name> (labels unit, fuzz);
#  - <name>_fuzz, with CNC_FUZZ (clang): the libFuzzer program that
#    scripts/fuzz.sh runs (docs/fuzzing.md).
# build/fuzz/<name>.txt lists the dictionary, corpus and seeds for the script.
function(cnc_fuzz_target name)
  cmake_parse_arguments(ARG "" "DICT" "SOURCES;DEPS;SEEDS" ${ARGN})
  set(corpus ${CMAKE_CURRENT_SOURCE_DIR}/corpus/${name})
  add_executable(${name}_fuzz_replay ${ARG_SOURCES} ${PROJECT_SOURCE_DIR}/tests/support/fuzz_replay_main.cpp)
  target_include_directories(${name}_fuzz_replay PRIVATE ${PROJECT_SOURCE_DIR})
  target_link_libraries(${name}_fuzz_replay PRIVATE cnc_build_flags ${ARG_DEPS})
  set(inputs ${ARG_SEEDS})
  if(EXISTS ${corpus})
    list(APPEND inputs ${corpus})
  endif()
  add_test(NAME fuzz.${name} COMMAND ${name}_fuzz_replay ${inputs})
  set_tests_properties(fuzz.${name} PROPERTIES LABELS "unit;fuzz" TIMEOUT 300)
  if(CNC_FUZZ)
    add_executable(${name}_fuzz ${ARG_SOURCES})
    target_include_directories(${name}_fuzz PRIVATE ${PROJECT_SOURCE_DIR})
    target_link_libraries(${name}_fuzz PRIVATE cnc_build_flags ${ARG_DEPS})
    target_link_options(${name}_fuzz PRIVATE -fsanitize=fuzzer)
  endif()
  set(list "corpus ${corpus}\n")
  if(ARG_DICT)
    string(APPEND list "dict ${CMAKE_CURRENT_SOURCE_DIR}/${ARG_DICT}\n")
  endif()
  foreach(seed IN LISTS ARG_SEEDS)
    string(APPEND list "seed ${seed}\n")
  endforeach()
  file(WRITE ${CMAKE_BINARY_DIR}/fuzz/${name}.txt "${list}")
endfunction()

# cnc_fuzz_seeds(<var> <glob>...): project files matching the globs (relative
# to the source root, e.g. configs/*.ini, tests/*.ini, searched recursively
# below that folder) as fuzz seeds.
function(cnc_fuzz_seeds var)
  set(found)
  foreach(g IN LISTS ARGN)
    get_filename_component(dir ${g} DIRECTORY)
    get_filename_component(pattern ${g} NAME)
    file(GLOB_RECURSE files ${PROJECT_SOURCE_DIR}/${dir}/${pattern})
    list(APPEND found ${files})
  endforeach()
  list(SORT found)
  set(${var} ${found} PARENT_SCOPE)
endfunction()

# cnc_fuzz_doc_seeds(<var> <kind>): the examples in docs/*.md and README.md
# as fuzz seeds: each fenced block whose first line marks it as <kind> (ini:
# a [SECTION] line; hal: a halcmd command; measurement: a CSV header with
# deviation_um, after comment lines) is written to
# build/fuzz/doc-seeds/<kind>/<page>-<n>; cmake runs again when a page changes.
function(cnc_fuzz_doc_seeds var kind)
  set(out ${CMAKE_BINARY_DIR}/fuzz/doc-seeds/${kind})
  file(REMOVE_RECURSE ${out})
  file(GLOB pages ${PROJECT_SOURCE_DIR}/docs/*.md)
  list(APPEND pages ${PROJECT_SOURCE_DIR}/README.md)
  set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS ${pages})
  set(found)
  foreach(page IN LISTS pages)
    file(READ ${page} text)
    get_filename_component(stem ${page} NAME_WE)
    set(n 0)
    while(TRUE)
      # The opening fence (at the start of a line), then its info string.
      string(FIND "${text}" "\n```" open)
      if(open EQUAL -1)
        break()
      endif()
      math(EXPR open "${open} + 4")
      string(SUBSTRING "${text}" ${open} -1 text)
      string(FIND "${text}" "\n" eol)
      if(eol EQUAL -1)
        break()
      endif()
      math(EXPR eol "${eol} + 1")
      string(SUBSTRING "${text}" ${eol} -1 text)
      string(FIND "${text}" "\n```" close)
      if(close EQUAL -1)
        break()
      endif()
      math(EXPR close "${close} + 1")
      string(SUBSTRING "${text}" 0 ${close} block)
      math(EXPR close "${close} + 3")
      string(SUBSTRING "${text}" ${close} -1 text)
      math(EXPR n "${n} + 1")
      set(match FALSE)
      if(kind STREQUAL "ini" AND block MATCHES "^[ \t\r\n]*\\[[A-Za-z0-9_]+\\][ \t\r]*\n")
        set(match TRUE)
      elseif(kind STREQUAL "hal" AND block MATCHES "^[ \t\r\n]*(loadrt|loadusr|net|setp|sets|addf|linkps|linksp|newsig|unlinkp) ")
        set(match TRUE)
      elseif(kind STREQUAL "measurement" AND block MATCHES "^(#[^\n]*\n)*[a-z_,]*deviation_um")
        set(match TRUE)
      endif()
      if(match)
        file(WRITE ${out}/${stem}-${n} "${block}")
        list(APPEND found ${out}/${stem}-${n})
      endif()
    endwhile()
  endforeach()
  set(${var} ${found} PARENT_SCOPE)
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
                       core/motion cia402 fieldbus/can fieldbus/canopen fieldbus/ethercat fieldbus/modbus vision comp core/io core/task
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
