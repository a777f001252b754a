# fuzz_build.cmake — the VOXVIS_FUZZ configuration, included by the top-level
# CMakeLists.txt in place of the rest of the project: voxvis::grid and
# voxvis::formats, whose parsers the targets fuzz, voxvis::import, and the
# targets of tests/fuzz. Nothing else is configured, so neither gRPC nor the
# renderer is looked for or built.
if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
  message(FATAL_ERROR
    "VOXVIS_FUZZ needs clang (libFuzzer comes with clang), but the C++ compiler is "
    "${CMAKE_CXX_COMPILER_ID} (${CMAKE_CXX_COMPILER}). Configure a new build directory with "
    "CC=clang CXX=clang++, as tests/fuzz/run_fuzz.sh does.")
endif()

find_package(glm REQUIRED)
find_package(nlohmann_json 3.10 REQUIRED)
include(cmake/openvdb.cmake)  # voxvis::grid's closed-mesh interiors.
# The importer's target links assimp, a shared library from Debian: it is not
# instrumented, so libFuzzer sees the coverage of voxvis's conversion only,
# and a crash inside assimp still stops the target with its stack.
find_package(assimp 5 REQUIRED)

# Everything compiled here carries libFuzzer's coverage instrumentation and is
# checked by AddressSanitizer (leaks included) and UBSan; UBSan stops at its
# first report so that libFuzzer keeps the input as a reproducer. Asserts stay
# on (-UNDEBUG comes after the build type's -DNDEBUG), nlohmann's own included.
# The targets themselves link with -fsanitize=fuzzer (tests/fuzz/CMakeLists.txt).
add_compile_options(-fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=all
  -fno-omit-frame-pointer -UNDEBUG)
add_link_options(-fsanitize=address,undefined)

set(CMAKE_RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR})
add_subdirectory(grid)
add_subdirectory(import)
add_subdirectory(tests/fuzz)
