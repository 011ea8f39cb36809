# pFUnit for the unit tests: an installed pFUnit 4 (found through CMAKE_PREFIX_PATH, PFUNIT_DIR or
# the default prefixes), or one built once from source at configure time and installed into
# TERRACE_PFUNIT_PREFIX, where later configures (of any checkout) find and reuse it.
#
#   -DTERRACE_PFUNIT_SOURCE=<pfunit-X.Y.Z-with-deps.tar.gz>   an archive with its dependencies in
#                                                            place (extern/fArgParse, gFTL, ...)
#   -DTERRACE_PFUNIT_SOURCE=<git URL of pFUnit's public repository>   cloned with --recursive at
#                                                            TERRACE_PFUNIT_GIT_TAG (needs network)
#   -DTERRACE_PFUNIT_PREFIX=<dir>   install prefix (default ~/.cache/terrace/pfunit-4.14.0)
#
# Sets PFUNIT_FOUND. Building takes about 10 minutes on one core, once per prefix; a file lock lets
# several configures share one prefix.
set(TERRACE_PFUNIT_SOURCE "$ENV{TERRACE_PFUNIT_SOURCE}" CACHE STRING
    "pFUnit source used when no installed pFUnit is found: a .tar.gz archive or a git URL")
set(TERRACE_PFUNIT_GIT_TAG "v4.14.0" CACHE STRING "tag cloned when TERRACE_PFUNIT_SOURCE is a git URL")
if(DEFINED ENV{HOME})
  set(_terrace_pfunit_default_prefix "$ENV{HOME}/.cache/terrace/pfunit-4.14.0")
else()
  set(_terrace_pfunit_default_prefix "${CMAKE_BINARY_DIR}/_pfunit/install")
endif()
set(TERRACE_PFUNIT_PREFIX "${_terrace_pfunit_default_prefix}" CACHE PATH
    "where a pFUnit built from TERRACE_PFUNIT_SOURCE is installed and looked for")

find_package(PFUNIT QUIET)
if(NOT PFUNIT_FOUND)
  find_package(PFUNIT QUIET PATHS "${TERRACE_PFUNIT_PREFIX}" NO_DEFAULT_PATH)
endif()

function(terrace_build_pfunit source prefix)
  set(work "${CMAKE_BINARY_DIR}/_pfunit")
  set(log "${work}/build.log")
  file(MAKE_DIRECTORY "${work}" "${prefix}")
  # one build per prefix at a time; the second configure waits and then finds the install
  file(LOCK "${prefix}/.terrace-build.lock" GUARD FUNCTION TIMEOUT 3600 RESULT_VARIABLE lock_rc)
  if(NOT lock_rc EQUAL 0)
    message(WARNING "Terrace: cannot lock ${prefix}: ${lock_rc}")
    return()
  endif()
  find_package(PFUNIT QUIET PATHS "${prefix}" NO_DEFAULT_PATH)
  if(PFUNIT_FOUND)
    return()
  endif()
  file(REMOVE_RECURSE "${work}/src" "${work}/build")
  file(MAKE_DIRECTORY "${work}/src")
  if(source MATCHES "\\.(tar\\.gz|tgz|tar\\.bz2|tar\\.xz|zip)$")
    get_filename_component(source "${source}" ABSOLUTE BASE_DIR "${PROJECT_SOURCE_DIR}")
    if(NOT EXISTS "${source}")
      message(FATAL_ERROR "Terrace: TERRACE_PFUNIT_SOURCE = ${source}: no such archive")
    endif()
    message(STATUS "Terrace: building pFUnit from ${source} into ${prefix} (about 10 minutes on one core, once)")
    execute_process(COMMAND ${CMAKE_COMMAND} -E tar xzf "${source}" WORKING_DIRECTORY "${work}/src"
                    RESULT_VARIABLE rc OUTPUT_QUIET ERROR_VARIABLE err)
    if(NOT rc EQUAL 0)
      message(FATAL_ERROR "Terrace: cannot unpack ${source}: ${err}")
    endif()
  else()
    find_package(Git REQUIRED)
    message(STATUS "Terrace: cloning pFUnit ${TERRACE_PFUNIT_GIT_TAG} from ${source} and building it into ${prefix}")
    execute_process(COMMAND "${GIT_EXECUTABLE}" clone --depth 1 --recursive --branch "${TERRACE_PFUNIT_GIT_TAG}"
                            "${source}" pFUnit WORKING_DIRECTORY "${work}/src" RESULT_VARIABLE rc ERROR_VARIABLE err)
    if(NOT rc EQUAL 0)
      message(FATAL_ERROR "Terrace: cannot clone pFUnit from ${source}: ${err}")
    endif()
  endif()
  file(GLOB tops LIST_DIRECTORIES true "${work}/src/*")
  list(LENGTH tops ntops)
  if(NOT ntops EQUAL 1 OR NOT EXISTS "${tops}/CMakeLists.txt")
    message(FATAL_ERROR "Terrace: ${source} does not hold one pFUnit source folder")
  endif()
  include(ProcessorCount)
  ProcessorCount(ncpu)
  if(ncpu EQUAL 0)
    set(ncpu 1)
  endif()
  foreach(step
      "${CMAKE_COMMAND};-S;${tops};-B;${work}/build;-DCMAKE_INSTALL_PREFIX=${prefix};-DCMAKE_BUILD_TYPE=Release;-DCMAKE_Fortran_COMPILER=${CMAKE_Fortran_COMPILER};-DSKIP_OPENMP=YES;-DENABLE_TESTS=NO"
      "${CMAKE_COMMAND};--build;${work}/build;-j;${ncpu}"
      "${CMAKE_COMMAND};--install;${work}/build")
    execute_process(COMMAND ${step} RESULT_VARIABLE rc OUTPUT_FILE "${log}.out" ERROR_FILE "${log}.err")
    file(READ "${log}.out" out)
    file(READ "${log}.err" err)
    file(APPEND "${log}" "${out}${err}")
    if(NOT rc EQUAL 0)
      message(FATAL_ERROR "Terrace: building pFUnit failed (see ${log}):\n${err}")
    endif()
  endforeach()
  file(REMOVE_RECURSE "${work}/src" "${work}/build")
endfunction()

if(NOT PFUNIT_FOUND AND TERRACE_PFUNIT_SOURCE)
  terrace_build_pfunit("${TERRACE_PFUNIT_SOURCE}" "${TERRACE_PFUNIT_PREFIX}")
  find_package(PFUNIT QUIET PATHS "${TERRACE_PFUNIT_PREFIX}" NO_DEFAULT_PATH)
  if(NOT PFUNIT_FOUND)
    message(FATAL_ERROR "Terrace: pFUnit was built into ${TERRACE_PFUNIT_PREFIX} but CMake does not find it there")
  endif()
endif()
