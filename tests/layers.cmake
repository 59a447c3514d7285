# layers.cmake - the rule that puts each test in its layer's folder
# (tests/README.md, "Layers"), checked each time CMake configures: a test in
# the wrong folder, or whose labels and folder disagree, stops the configure
# with what is wrong and where the test belongs.
#
#   unit/       one process, the code under test linked in, nothing outside
#               the build: no Vulkan device, no skyd, no other program.
#               Label unit.
#   numerical/  numbers against a reference (NREL, Coulson, the path tracer,
#               the reference model, the half's rounding); may use the
#               Vulkan device, starts no skyd. Label numerical.
#   daemon/     starts the real skyd built here and talks to it as its
#               clients do; needs nothing outside the build but the Vulkan
#               device. Labels integration and daemon (and numerical for
#               those that also measure numbers).
#   system/     needs a program or a service from outside the build: umockdev,
#               mosquitto, systemd's tools, Xvfb, an install tree, strace, socat.
#               Labels integration and system.
#   fuzz/       libFuzzer targets (LLVMFuzzerTestOneInput). Label fuzz.
#
# What is checked: every test program (*.c, *.sh) under tests/ lies in a
# layer's folder (sanitizers/ holds no test: the sanitizer pass's
# suppressions and its preloaded library, tests/CMakeLists.txt); tests are added only by the layers' CMakeLists.txt, each
# of which names its layer (skyd_layer); each
# test carries its folder's labels and no other layer's (but numerical in
# daemon/ and system/); the programs a layer builds take their sources under
# tests/ from its own folder; and what a source includes or runs fits its
# folder (the harnesses that start skyd, the Vulkan device, the outside
# programs named above, the libFuzzer entry point).

set(SKYD_LAYERS unit numerical daemon system fuzz)
set(SKYD_LAYER_LABELS_unit unit)
set(SKYD_LAYER_LABELS_numerical numerical)
set(SKYD_LAYER_LABELS_daemon integration daemon)
set(SKYD_LAYER_LABELS_system integration system)
set(SKYD_LAYER_LABELS_fuzz fuzz)
# Labels a test may carry besides its layer's: what else it proves.
set(SKYD_LAYER_EXTRA_daemon numerical)
set(SKYD_LAYER_EXTRA_system numerical)

# What a source's text says it needs (regular expressions over the file).
set(SKYD_NEEDS_SKYD "#include \"(daemon|fdstore|notify|sync)_harness\\.h\"|SKYD_BINARY")
set(SKYD_NEEDS_DEVICE "#include \"(vk_or_skip|test_glsl_vk|sky_probe|eng)\\.h\"")
set(SKYD_NEEDS_OUTSIDE "umockdev|mosquitto|Xvfb|systemd-socket-activate|systemd-analyze|strace|DESTDIR")
set(SKYD_NEEDS_FUZZER "LLVMFuzzerTestOneInput")

# Appends to the caller's problems where the text of tests/<layer>/<file>
# does not fit its layer.
function(skyd_check_source layer file)
  file(READ ${SKYD_TESTS_DIR}/${layer}/${file} text)
  set(where "tests/${layer}/${file}")
  set(found)
  foreach(key SKYD DEVICE OUTSIDE FUZZER)
    if(text MATCHES "${SKYD_NEEDS_${key}}")
      list(APPEND found ${key})
    endif()
  endforeach()
  set(p ${problems})
  if("SKYD" IN_LIST found AND layer MATCHES "^(unit|numerical|fuzz)$")
    list(APPEND p "${where} starts skyd: it belongs in tests/daemon (or tests/system)")
  endif()
  if("DEVICE" IN_LIST found AND layer STREQUAL "unit")
    list(APPEND p "${where} needs the Vulkan device: it belongs in tests/numerical or tests/daemon")
  endif()
  if("OUTSIDE" IN_LIST found AND NOT layer STREQUAL "system")
    list(APPEND p "${where} runs a program from outside the build: it belongs in tests/system")
  endif()
  if(NOT "OUTSIDE" IN_LIST found AND layer STREQUAL "system")
    list(APPEND p "${where} needs nothing from outside the build: it belongs in another layer")
  endif()
  if("FUZZER" IN_LIST found AND NOT layer STREQUAL "fuzz")
    list(APPEND p "${where} is a libFuzzer target: it belongs in tests/fuzz")
  endif()
  if(NOT "FUZZER" IN_LIST found AND layer STREQUAL "fuzz")
    list(APPEND p "${where} is no libFuzzer target: it belongs in another layer")
  endif()
  if(NOT "SKYD" IN_LIST found AND layer STREQUAL "daemon" AND file MATCHES "\\.c$")
    list(APPEND p "${where} starts no skyd: it belongs in another layer")
  endif()
  set(problems ${p} PARENT_SCOPE)
endfunction()

# Each layer's CMakeLists.txt opens with skyd_layer(<its folder's name>):
# the tests and programs it adds are checked once it has added them all.
function(skyd_layer layer)
  set_property(DIRECTORY PROPERTY SKYD_LAYER ${layer})
  cmake_language(DEFER CALL skyd_check_layer)
  # The sanitizers' settings for its tests (tests/CMakeLists.txt).
  if(SKYD_SANITIZE_KIND)
    cmake_language(DEFER CALL skyd_sanitizer_env)
  endif()
endfunction()

# Run at the end of tests/<layer>/CMakeLists.txt, in its scope (where its
# tests' properties can be read); what is wrong goes to the global property
# SKYD_LAYER_PROBLEMS.
function(skyd_check_layer)
  get_property(layer DIRECTORY PROPERTY SKYD_LAYER)
  set(problems)
  set(dir ${SKYD_TESTS_DIR}/${layer})
  if(NOT CMAKE_CURRENT_SOURCE_DIR STREQUAL dir)
    file(RELATIVE_PATH rel ${PROJECT_SOURCE_DIR} ${CMAKE_CURRENT_SOURCE_DIR})
    list(APPEND problems "${rel}/CMakeLists.txt calls skyd_layer(${layer})")
  endif()
  get_property(tests DIRECTORY PROPERTY TESTS)
  foreach(t ${tests})
    get_test_property(${t} LABELS labels)
    foreach(l ${SKYD_LAYER_LABELS_${layer}})
      if(NOT l IN_LIST labels)
        list(APPEND problems "${t} (tests/${layer}) lacks the label ${l}")
      endif()
    endforeach()
    foreach(l ${labels})
      if(NOT l IN_LIST SKYD_LAYER_LABELS_${layer} AND NOT l IN_LIST SKYD_LAYER_EXTRA_${layer})
        list(APPEND problems "${t} (tests/${layer}) is labelled ${l}, which is not its folder's layer")
      endif()
    endforeach()
  endforeach()
  get_property(targets DIRECTORY PROPERTY BUILDSYSTEM_TARGETS)
  foreach(target ${targets})
    get_target_property(sources ${target} SOURCES)
    foreach(s ${sources})
      cmake_path(ABSOLUTE_PATH s BASE_DIRECTORY ${dir} NORMALIZE)
      cmake_path(IS_PREFIX SKYD_TESTS_DIR "${s}" NORMALIZE in_tests)
      cmake_path(IS_PREFIX dir "${s}" NORMALIZE in_layer)
      if(in_tests AND NOT in_layer)
        file(RELATIVE_PATH rel ${PROJECT_SOURCE_DIR} ${s})
        list(APPEND problems "${target} (tests/${layer}) is built from ${rel}, outside its folder")
      endif()
    endforeach()
  endforeach()
  file(GLOB files RELATIVE ${dir} ${dir}/*.c ${dir}/*.sh)
  foreach(f ${files})
    skyd_check_source(${layer} ${f})
  endforeach()
  set_property(GLOBAL APPEND PROPERTY SKYD_LAYER_PROBLEMS ${problems})
endfunction()

# After the layers' folders: the test programs outside them, tests added
# elsewhere, and what the layers' own checks found; stops the configure if
# anything is wrong.
function(skyd_check_layers)
  get_property(problems GLOBAL PROPERTY SKYD_LAYER_PROBLEMS)
  file(GLOB_RECURSE programs RELATIVE ${SKYD_TESTS_DIR} ${SKYD_TESTS_DIR}/*.c ${SKYD_TESTS_DIR}/*.sh)
  list(JOIN SKYD_LAYERS ", " names)
  foreach(f ${programs})
    string(REGEX MATCH "^[^/]+" top "${f}")
    if(NOT top IN_LIST SKYD_LAYERS AND NOT top STREQUAL "sanitizers")
      list(APPEND problems "tests/${f} is outside the layers' folders (${names})")
    endif()
  endforeach()
  get_property(tests DIRECTORY PROPERTY TESTS)
  foreach(t ${tests})
    list(APPEND problems "${t} is added by tests/CMakeLists.txt, not by its layer's folder")
  endforeach()
  foreach(layer ${SKYD_LAYERS})
    get_property(declared DIRECTORY ${layer} PROPERTY SKYD_LAYER)
    if(NOT declared STREQUAL layer)
      list(APPEND problems "tests/${layer}/CMakeLists.txt does not open with skyd_layer(${layer})")
    endif()
  endforeach()
  if(problems)
    list(JOIN problems "\n  " text)
    message(FATAL_ERROR "tests out of their layer (tests/layers.cmake, tests/README.md):\n  ${text}")
  endif()
endfunction()
