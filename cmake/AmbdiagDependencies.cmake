# Finds the Debian packages listed in deploy/install-deps.sh.

find_package(nlohmann_json 3.11 REQUIRED CONFIG)

if(NOT AMBDIAG_FUZZ_ONLY)
  find_package(Eigen3 3.4 REQUIRED CONFIG)

  # SuiteSparse 5.12 on Debian ships neither CMake config nor pkg-config files.
  find_path(AMBDIAG_SUITESPARSE_INCLUDE umfpack.h PATH_SUFFIXES suitesparse REQUIRED)
  add_library(ambdiag_suitesparse INTERFACE)
  target_include_directories(ambdiag_suitesparse SYSTEM INTERFACE ${AMBDIAG_SUITESPARSE_INCLUDE})
  foreach(lib umfpack klu btf cholmod amd colamd camd ccolamd suitesparseconfig)
    find_library(AMBDIAG_SS_${lib} ${lib} REQUIRED)
    target_link_libraries(ambdiag_suitesparse INTERFACE ${AMBDIAG_SS_${lib}})
  endforeach()
  add_library(SuiteSparse::all ALIAS ambdiag_suitesparse)

  # Historian and REST (issue 5).
  find_package(SQLite3 REQUIRED)
  # The historian's second backend (issue 22): plain libpq (libpq-dev).
  find_package(PostgreSQL REQUIRED)
  find_package(PkgConfig REQUIRED)
  pkg_check_modules(HTTPLIB REQUIRED IMPORTED_TARGET cpp-httplib)
  # HTTPS for the REST service (issue 21): Debian's cpp-httplib is built
  # with CPPHTTPLIB_OPENSSL_SUPPORT; the TLS context is set up with OpenSSL.
  find_package(OpenSSL REQUIRED)
  # The REST server gzips its text replies itself (server/src/http_compress.h).
  find_package(ZLIB REQUIRED)
endif()

if(AMBDIAG_BUILD_TESTS OR AMBDIAG_FUZZ)
  find_package(GTest REQUIRED CONFIG)
endif()
if(AMBDIAG_BUILD_BENCH AND NOT AMBDIAG_FUZZ_ONLY)
  find_package(benchmark REQUIRED CONFIG)
endif()

# Streaming (issue 5): Cyclone DDS (C API only on Debian; idlc_generate emits C).
if(NOT AMBDIAG_FUZZ_ONLY)
  find_package(CycloneDDS REQUIRED CONFIG)
endif()
