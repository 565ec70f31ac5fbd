# Runs `mpirun -np NP cellray-mpi-render FLAGS` and expects exit code CODE
# (mpirun passes a rank's non-zero code on) and stderr matching PATTERN,
# within TIMEOUT seconds: a failing rank must not leave the others waiting.
execute_process(COMMAND ${MPIEXEC} ${MPI_FLAGS} -np ${NP} ${MPI_RENDER} ${FLAGS}
  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err TIMEOUT 60)
if(NOT rc STREQUAL "${CODE}")
  message(FATAL_ERROR "expected exit ${CODE}, got '${rc}': ${out} ${err}")
endif()
if(NOT err MATCHES "${PATTERN}")
  message(FATAL_ERROR "stderr does not match '${PATTERN}': ${err}")
endif()
message(STATUS "exit ${rc}: ${err}")
