# Users who add dynbvh as source (add_subdirectory, FetchContent) compile its headers under their own
# warning flags. This check compiles, with one compiler (syntax only, so it is fast), under
#   -std=c++20 -Wall -Wextra -Wpedantic -Wconversion -Wsign-conversion -Wshadow -Werror
# MODE=headers:         every public header (include/dynbvh/**/*.hpp) alone, as `#include <dynbvh/...>`
#                       (with -DALONE=ON; else all of them in one file: the second compiler's warnings);
# MODE=instantiations:  SOURCES (tests/strict_warnings.cpp: every public template instantiated;
#                       examples/quickstart.cpp: the README's program) without a backend, and with
#                       -fopenmp (HAVE_OMP) and -DDYNBVH_WITH_TBB=1 (HAVE_TBB); BACKEND_SOURCES
#                       (tests/readme_snippets.cpp: the README's code) only with both backends;
#                       -DBACKENDS_ONLY=ON: SOURCES only with the backends when there are any.
# -DCXX=<compiler> -DMODE=headers|instantiations -DINCLUDE_DIR=<include/> -DSOURCES=<a.cpp;b.cpp>
# -DWORK_DIR=<scratch folder> [-DHAVE_OMP=ON] [-DHAVE_TBB=ON] [-DBACKEND_SOURCES=<c.cpp>]
# [-DSYSTEM_INCLUDE=<dirs of TBB and doctest, passed as -isystem>]
# Prints "...: skipped" (the test's SKIP_REGULAR_EXPRESSION) when CXX was not found.
if(NOT CXX OR NOT EXISTS "${CXX}")
  message("strict warnings: no compiler '${CXX}' (tools/deps.sh installs g++ and clang): skipped")
  return()
endif()
set(strict -std=c++20 -Wall -Wextra -Wpedantic -Wconversion -Wsign-conversion -Wshadow -Werror -fsyntax-only
    -I${INCLUDE_DIR})
foreach(d ${SYSTEM_INCLUDE})
  list(APPEND strict -isystem ${d})   # as CMake passes an imported target's headers
endforeach()
set(failures "")
set(checked 0)

function(check what)
  execute_process(COMMAND ${CXX} ${strict} ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE out)
  math(EXPR n "${checked} + 1")
  set(checked ${n} PARENT_SCOPE)
  if(rc)
    string(APPEND failures "\n--- ${what}:\n${out}")
    set(failures "${failures}" PARENT_SCOPE)
  endif()
endfunction()

if(MODE STREQUAL "headers")
  file(GLOB_RECURSE headers RELATIVE ${INCLUDE_DIR} ${INCLUDE_DIR}/dynbvh/*.hpp)
  list(SORT headers)
  file(MAKE_DIRECTORY ${WORK_DIR})
  if(ALONE)
    foreach(h ${headers})
      string(MAKE_C_IDENTIFIER ${h} id)
      file(WRITE ${WORK_DIR}/${id}.cpp "#include <${h}>\n")
      check("${h} alone" ${WORK_DIR}/${id}.cpp)
    endforeach()
  else()
    set(all "")
    foreach(h ${headers})
      string(APPEND all "#include <${h}>\n")
    endforeach()
    file(WRITE ${WORK_DIR}/all_headers.cpp "${all}")
    check("all headers in one file" ${WORK_DIR}/all_headers.cpp)
  endif()
elseif(MODE STREQUAL "instantiations")
  set(backends "")
  if(HAVE_OMP)
    list(APPEND backends -fopenmp)
  endif()
  if(HAVE_TBB)
    list(APPEND backends -DDYNBVH_WITH_TBB=1)
  endif()
  list(JOIN backends " " backends_text)
  foreach(src ${SOURCES})
    get_filename_component(name ${src} NAME)
    if(NOT backends OR NOT BACKENDS_ONLY)
      check("${name}" ${src})
    endif()
    if(backends)
      check("${name} with ${backends_text}" ${backends} ${src})
    endif()
  endforeach()
  if(HAVE_OMP AND HAVE_TBB)
    foreach(src ${BACKEND_SOURCES})
      get_filename_component(name ${src} NAME)
      check("${name} with ${backends_text}" ${backends} ${src})
    endforeach()
  endif()
else()
  message(FATAL_ERROR "strict warnings: MODE must be headers or instantiations, not '${MODE}'")
endif()

if(failures)
  message(FATAL_ERROR "strict warnings (${CXX}): warnings or errors in${failures}")
endif()
message(STATUS "strict warnings (${CXX}, ${MODE}): ${checked} compiles, no warning")
