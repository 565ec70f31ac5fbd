# Runs cellray-render and `mpirun -np NP cellray-mpi-render` with the same
# flags and compares the two PNGs (png_rmse: RMSE and largest difference in
# 8-bit levels). -D: RENDER MPI_RENDER MPIEXEC NP PNG_RMSE OUT FLAGS (a
# ;-list) MAX_RMSE MAX_DIFF [MPI_FLAGS (;-list: mpirun's own)].
# With PIECES and SPLIT_PVTU: the mesh (the first of FLAGS) is split into
# PIECES .vtu files under OUT and cellray-mpi-render reads their .pvtu
# instead, while cellray-render reads the original file.
# With EXPECT_OUT / REFUSE_OUT: cellray-mpi-render's stdout (add --stats to
# FLAGS) must / must not match that regex.
file(MAKE_DIRECTORY ${OUT})
set(single ${OUT}/single.png)
set(multi ${OUT}/mpi_np${NP}.png)
execute_process(COMMAND ${RENDER} ${FLAGS} -o ${single} RESULT_VARIABLE rc ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "cellray-render failed (${rc}): ${err}")
endif()
set(mpi_args ${FLAGS})
if(PIECES)
  list(GET FLAGS 0 mesh)
  set(stem ${OUT}/pieces_np${NP})
  execute_process(COMMAND ${SPLIT_PVTU} ${mesh} ${PIECES} ${stem} RESULT_VARIABLE rc ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "split_pvtu failed (${rc}): ${err}")
  endif()
  list(REMOVE_AT mpi_args 0)
  list(PREPEND mpi_args ${stem}.pvtu)
endif()
execute_process(COMMAND ${MPIEXEC} ${MPI_FLAGS} -np ${NP} ${MPI_RENDER} ${mpi_args} -o ${multi}
  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err TIMEOUT 240)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "mpirun -np ${NP} cellray-mpi-render failed (${rc}): ${out} ${err}")
endif()
if(EXPECT_OUT AND NOT out MATCHES "${EXPECT_OUT}")
  message(FATAL_ERROR "cellray-mpi-render's output does not match '${EXPECT_OUT}': ${out}")
endif()
if(REFUSE_OUT AND out MATCHES "${REFUSE_OUT}")
  message(FATAL_ERROR "cellray-mpi-render's output matches '${REFUSE_OUT}': ${out}")
endif()
execute_process(COMMAND ${PNG_RMSE} ${single} ${multi} ${MAX_RMSE} ${MAX_DIFF} RESULT_VARIABLE rc OUTPUT_VARIABLE out)
message(STATUS "${out}")
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "the images differ: ${out}")
endif()
