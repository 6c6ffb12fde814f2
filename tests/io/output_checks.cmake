# Output tests beyond the Fortran programs (included from tests/CMakeLists.txt).
# Builds without HDF5 compile stand-ins that refuse to write: the HDF5 tests then exit 77.
set_tests_properties(io.test_frame_writer io.test_checkpoint PROPERTIES SKIP_RETURN_CODE 77)
if(RICOCHET_USE_HDF5)
  # io.frame_writer_xdmf reads what io.test_frame_writer wrote, with VTK's XDMF reader (the
  # reader ParaView uses): it runs after it, in its folder, and only if it passed.
  set_tests_properties(io.test_frame_writer PROPERTIES FIXTURES_SETUP frame_output)
  add_test(NAME io.frame_writer_xdmf
           COMMAND ${RICOCHET_PYTHON} ${CMAKE_CURRENT_SOURCE_DIR}/io/check_xdmf.py output
           WORKING_DIRECTORY ${CMAKE_CURRENT_BINARY_DIR}/run/io_test_frame_writer)
  set_tests_properties(io.frame_writer_xdmf PROPERTIES FIXTURES_REQUIRED frame_output
                       DEPENDS io.test_frame_writer LABELS io ENVIRONMENT "${RICOCHET_TEST_ENV}" TIMEOUT 120)
endif()

# tools/plot_history.py turns a history file into a PNG (exit code 0 only after saving it).
add_test(NAME io.plot_history
         COMMAND ${RICOCHET_PYTHON} ${PROJECT_SOURCE_DIR}/tools/plot_history.py
                 ${RICOCHET_TEST_DATA}/history_small.csv --out history_small.png
         WORKING_DIRECTORY ${CMAKE_CURRENT_BINARY_DIR}/run)
set_tests_properties(io.plot_history PROPERTIES LABELS io TIMEOUT 120)
