# Using exec::omp / exec::tbb without its backend fails to compile with a message naming the target to
# link (include/dynbvh/executor.hpp); with the backend the same file compiles. Syntax checks only (fast).
# -DCXX=<compiler> -DINCLUDE_DIR=<include/> -DSOURCE=<missing_backend.cpp> -DHAVE_OMP=ON|OFF -DHAVE_TBB=ON|OFF
function(compile expect_ok what)
  execute_process(COMMAND ${CXX} -std=c++20 -fsyntax-only -I${INCLUDE_DIR} ${ARGN} ${SOURCE}
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE out)
  if(expect_ok AND rc)
    message(FATAL_ERROR "${what}: expected to compile, but:\n${out}")
  elseif(NOT expect_ok AND NOT rc)
    message(FATAL_ERROR "${what}: compiled, but must fail")
  endif()
  set(out "${out}" PARENT_SCOPE)
endfunction()

compile(FALSE "exec::omp without OpenMP" -DUSE_OMP)
if(NOT out MATCHES "dynbvh::exec::omp needs OpenMP: link dynbvh::omp \\(or compile with -fopenmp\\)")
  message(FATAL_ERROR "exec::omp without OpenMP: the error does not say what to link:\n${out}")
endif()
compile(FALSE "exec::tbb without TBB" -DUSE_TBB)
if(NOT out MATCHES "dynbvh::exec::tbb needs oneTBB: link dynbvh::tbb")
  message(FATAL_ERROR "exec::tbb without TBB: the error does not say what to link:\n${out}")
endif()
if(HAVE_OMP)
  compile(TRUE "exec::omp with -fopenmp" -DUSE_OMP -fopenmp)
endif()
if(HAVE_TBB)
  compile(TRUE "exec::tbb with DYNBVH_WITH_TBB" -DUSE_TBB -DDYNBVH_WITH_TBB=1)
endif()
message(STATUS "exec::omp / exec::tbb without their backend: clear errors; with it: compiles")
