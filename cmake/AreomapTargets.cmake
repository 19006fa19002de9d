# Helpers that keep every areomap target built the same way.

# Compiler flags shared by all areomap code (libraries, apps, tests, benches).
add_library(areomap_build_flags INTERFACE)
target_compile_options(areomap_build_flags INTERFACE
  -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor -Wconversion -Wno-sign-conversion
  $<$<BOOL:${AREOMAP_WERROR}>:-Werror>
  $<$<BOOL:${AREOMAP_SANITIZE}>:-fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined>)
# A unity build (the `ci` preset: each library's sources compiled in batches of 8, which parses the
# heavy headers once per batch) includes every source into a batch file, so GCC takes each for a
# header and would warn that a class there holds a type from its anonymous namespace.
if(CMAKE_UNITY_BUILD AND CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
  target_compile_options(areomap_build_flags INTERFACE -Wno-subobject-linkage)
endif()
target_link_options(areomap_build_flags INTERFACE
  $<$<BOOL:${AREOMAP_SANITIZE}>:-fsanitize=address,undefined>)
# Fuzzing: coverage feedback for libFuzzer in every areomap object; the fuzz targets add the
# libFuzzer driver (-fsanitize=fuzzer) at link time (fuzz/CMakeLists.txt).
if(AREOMAP_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID MATCHES "Clang")
    message(FATAL_ERROR "AREOMAP_FUZZ needs clang (libFuzzer); use the `fuzz` preset")
  endif()
  target_compile_options(areomap_build_flags INTERFACE
    -fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined
    -fno-omit-frame-pointer)
  target_link_options(areomap_build_flags INTERFACE -fsanitize=address,undefined)
endif()

# areomap_add_library(NAME <module> ALIAS <alias> SOURCES ... PUBLIC_LINK_LIBS ... PRIVATE_LINK_LIBS ...)
# Creates a static library with public headers in <dir>/include, visible layering through
# PUBLIC_LINK_LIBS (COLMAP_ADD_LIBRARY style).
function(areomap_add_library)
  cmake_parse_arguments(ARG "" "NAME;ALIAS" "SOURCES;PUBLIC_LINK_LIBS;PRIVATE_LINK_LIBS" ${ARGN})
  add_library(${ARG_NAME} STATIC ${ARG_SOURCES})
  # Linked into the Python module's shared object too (cmake/Python.cmake).
  set_target_properties(${ARG_NAME} PROPERTIES POSITION_INDEPENDENT_CODE ${AREOMAP_PYTHON})
  add_library(${ARG_ALIAS} ALIAS ${ARG_NAME})
  target_include_directories(${ARG_NAME} PUBLIC ${CMAKE_CURRENT_SOURCE_DIR}/include)
  target_link_libraries(${ARG_NAME}
    PUBLIC ${ARG_PUBLIC_LINK_LIBS}
    PRIVATE areomap_build_flags ${ARG_PRIVATE_LINK_LIBS})
endfunction()
