# mpi.parallel_frame_contents reads what mpi.test_parallel_output wrote from two ranks
# (h5py, serial): it runs after it, in its folder, and only if it passed.
set_tests_properties(mpi.test_parallel_output PROPERTIES SKIP_RETURN_CODE 77)
if(RICOCHET_USE_HDF5)
  set_tests_properties(mpi.test_parallel_output PROPERTIES FIXTURES_SETUP parallel_frames)
  add_test(NAME mpi.parallel_frame_contents
           COMMAND ${RICOCHET_PYTHON} ${CMAKE_CURRENT_SOURCE_DIR}/mpi/check_parallel_frame.py output
           WORKING_DIRECTORY ${CMAKE_CURRENT_BINARY_DIR}/run/mpi_test_parallel_output)
  set_tests_properties(mpi.parallel_frame_contents PROPERTIES FIXTURES_REQUIRED parallel_frames
                       DEPENDS mpi.test_parallel_output LABELS "mpi;io" ENVIRONMENT "${RICOCHET_TEST_ENV}" TIMEOUT 120)
endif()
