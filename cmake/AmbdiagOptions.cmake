# Warnings, sanitizers and a helper to declare project libraries consistently.

add_library(ambdiag_warnings INTERFACE)
target_compile_options(ambdiag_warnings INTERFACE
  -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor -Wold-style-cast
  -Wcast-align -Woverloaded-virtual -Wimplicit-fallthrough
  $<$<BOOL:${AMBDIAG_WERROR}>:-Werror>)

# Compressed debug sections in linked programs (zlib; gdb reads them): each
# test program links the algorithms library with its debug info, about
# 110 MB a program uncompressed, 28 MB compressed; a build tree drops from
# 18 to about 8 GB. Objects stay uncompressed, so ccache keeps its hits.
include(CheckLinkerFlag)
check_linker_flag(CXX -gz AMBDIAG_LINKER_GZ)
if(AMBDIAG_LINKER_GZ)
  add_link_options(-gz)
endif()

if(AMBDIAG_SANITIZE)
  add_compile_options(-fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined)
  add_link_options(-fsanitize=address,undefined)
endif()

if(AMBDIAG_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID MATCHES "Clang")
    message(FATAL_ERROR "AMBDIAG_FUZZ needs clang (CXX=clang++)")
  endif()
  # Instrument everything for coverage; the fuzzers link the libFuzzer main.
  add_compile_options(-fsanitize=fuzzer-no-link,address,undefined -fno-omit-frame-pointer)
  add_link_options(-fsanitize=address,undefined)
endif()

# ambdiag_library(NAME SOURCES... ) : a library with public headers in include/.
function(ambdiag_library name)
  add_library(${name} ${ARGN})
  target_include_directories(${name}
    PUBLIC ${CMAKE_CURRENT_SOURCE_DIR}/include
    PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/src)
  target_link_libraries(${name} PRIVATE ambdiag_warnings)
endfunction()
