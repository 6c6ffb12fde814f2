# mpi.parallel_frame_contents reads what mpi.test_parallel_output wrote from two ranks
# (h5py, serial): it runs after it, in its folder, and only if it passed.
if(TEST mpi.test_parallel_output)
  set_tests_properties(mpi.test_parallel_output PROPERTIES SKIP_RETURN_CODE 77)
endif()
if(RICOCHET_USE_HDF5)
  set_tests_properties(mpi.test_parallel_output PROPERTIES FIXTURES_SETUP parallel_frames)
  add_test(NAME mpi.parallel_frame_contents
           COMMAND ${RICOCHET_PYTHON} ${CMAKE_CURRENT_SOURCE_DIR}/mpi/check_parallel_frame.py output
           WORKING_DIRECTORY ${CMAKE_CURRENT_BINARY_DIR}/run/mpi_test_parallel_output)
  set_tests_properties(mpi.parallel_frame_contents PROPERTIES FIXTURES_REQUIRED parallel_frames
                       DEPENDS mpi.test_parallel_output LABELS "mpi;io" ENVIRONMENT "${RICOCHET_TEST_ENV}" TIMEOUT 120)
endif()

# The same deck on 1 and 2 ranks gives bitwise identical results.
if(RICOCHET_USE_HDF5)
  set(workdir ${CMAKE_CURRENT_BINARY_DIR}/run/mpi_rank_independence)
  file(MAKE_DIRECTORY ${workdir})
  add_test(NAME mpi.rank_independence
           COMMAND ${RICOCHET_PYTHON} ${CMAKE_CURRENT_SOURCE_DIR}/mpi/check_rank_independence.py
                   $<TARGET_FILE:ricochet> ${PROJECT_SOURCE_DIR}/input/validation/free_fall.nml ${workdir}
                   ${MPIEXEC_EXECUTABLE} ${MPIEXEC_PREFLAGS}
           WORKING_DIRECTORY ${workdir})
  set_tests_properties(mpi.rank_independence PROPERTIES LABELS "mpi;regression" ENVIRONMENT "${RICOCHET_TEST_ENV}"
                       TIMEOUT 300)
  # Newmark's answer depends on the steps: identical only if both runs take the same ones
  # (each rank used to limit the step by its own bodies alone).
  set(workdir ${CMAKE_CURRENT_BINARY_DIR}/run/mpi_rank_independence_newmark)
  file(MAKE_DIRECTORY ${workdir})
  add_test(NAME mpi.rank_independence_newmark
           COMMAND ${RICOCHET_PYTHON} ${CMAKE_CURRENT_SOURCE_DIR}/mpi/check_rank_independence.py --rotation newmark
                   $<TARGET_FILE:ricochet> ${PROJECT_SOURCE_DIR}/input/validation/free_fall.nml ${workdir}
                   ${MPIEXEC_EXECUTABLE} ${MPIEXEC_PREFLAGS}
           WORKING_DIRECTORY ${workdir})
  set_tests_properties(mpi.rank_independence_newmark PROPERTIES LABELS "mpi;regression"
                       ENVIRONMENT "${RICOCHET_TEST_ENV}" TIMEOUT 300)
endif()

# Decks with contacts on 2 ranks: until the domain decomposition lands, bodies that may
# touch run on one rank, so the answer is the one-rank answer bit for bit (the 10-cube
# stack used to fall through the floor on 2 ranks, the cradle's balls through each other).
if(RICOCHET_USE_HDF5)
  foreach(deck stack_10_cubes newtons_cradle)
    set(workdir ${CMAKE_CURRENT_BINARY_DIR}/run/mpi_rank_independence_${deck})
    file(MAKE_DIRECTORY ${workdir})
    add_test(NAME mpi.rank_independence_${deck}
             COMMAND ${RICOCHET_PYTHON} ${CMAKE_CURRENT_SOURCE_DIR}/mpi/check_rank_independence.py
                     $<TARGET_FILE:ricochet> ${PROJECT_SOURCE_DIR}/input/validation/${deck}.nml ${workdir}
                     ${MPIEXEC_EXECUTABLE} ${MPIEXEC_PREFLAGS}
             WORKING_DIRECTORY ${workdir})
    set_tests_properties(mpi.rank_independence_${deck} PROPERTIES LABELS "mpi;regression"
                         ENVIRONMENT "${RICOCHET_TEST_ENV}" TIMEOUT 300)
  endforeach()
endif()

# The domain decomposition of a scene whose bodies cannot interact (bricks, windows,
# migration with the bodies' anchors, output in global-id blocks): 1, 2 and 4 ranks write
# the same files, and restarts continue across rank counts (4 -> 2, 4 -> 1, 1 -> 4).
if(RICOCHET_USE_HDF5)
  set(workdir ${CMAKE_CURRENT_BINARY_DIR}/run/mpi_decomposition)
  file(MAKE_DIRECTORY ${workdir})
  add_test(NAME mpi.decomposition_crossing_bricks
           COMMAND ${RICOCHET_PYTHON} ${CMAKE_CURRENT_SOURCE_DIR}/mpi/check_decomposition.py
                   $<TARGET_FILE:ricochet> ${PROJECT_SOURCE_DIR}/input/validation/crossing_bricks.nml ${workdir}
                   ${MPIEXEC_EXECUTABLE} ${MPIEXEC_PREFLAGS}
           WORKING_DIRECTORY ${workdir})
  set_tests_properties(mpi.decomposition_crossing_bricks PROPERTIES LABELS "mpi;regression"
                       ENVIRONMENT "${RICOCHET_TEST_ENV}" TIMEOUT 300)
endif()

# The local loop kept through migrations (event_loop%remap_bodies): audited windows on 2
# ranks, frames and history those of one rank, window ends certifying the arrivals only.
if(RICOCHET_USE_HDF5)
  set(workdir ${CMAKE_CURRENT_BINARY_DIR}/run/mpi_window_remap)
  file(MAKE_DIRECTORY ${workdir})
  add_test(NAME mpi.decomposition_window_remap
           COMMAND ${RICOCHET_PYTHON} ${CMAKE_CURRENT_SOURCE_DIR}/mpi/check_window_remap.py
                   $<TARGET_FILE:ricochet> ${RICOCHET_TEST_DATA}/decomposition/window_remap.nml ${workdir}
                   ${MPIEXEC_EXECUTABLE} ${MPIEXEC_PREFLAGS}
           WORKING_DIRECTORY ${workdir})
  set_tests_properties(mpi.decomposition_window_remap PROPERTIES LABELS "mpi;regression"
                       ENVIRONMENT "${RICOCHET_TEST_ENV}" TIMEOUT 300)
endif()

# The start-up checks shared among ranks (overlap test, contact_possible's sweep): on 1 to 4
# ranks the same overlap error names the same bodies, and the notice the same pair.
if(RICOCHET_USE_HDF5)
  set(workdir ${CMAKE_CURRENT_BINARY_DIR}/run/mpi_shared_startup)
  file(MAKE_DIRECTORY ${workdir})
  add_test(NAME mpi.shared_startup_checks
           COMMAND ${RICOCHET_PYTHON} ${CMAKE_CURRENT_SOURCE_DIR}/mpi/check_shared_startup.py
                   $<TARGET_FILE:ricochet> ${workdir} ${MPIEXEC_EXECUTABLE} ${MPIEXEC_PREFLAGS}
           WORKING_DIRECTORY ${workdir})
  set_tests_properties(mpi.shared_startup_checks PROPERTIES LABELS "mpi;regression"
                       ENVIRONMENT "${RICOCHET_TEST_ENV}" TIMEOUT 300)
endif()

# Contacts between bodies of different ranks (cross-rank windows: ghosts, runs repeated to
# the first time a ghost is needed, cross-rank impacts by the lower id's owner): face, edge,
# a gas on 2-4 ranks with restarts across rank counts, the billiards break; the same files
# as one rank, bit for bit; an impulse group across two brick faces stops with an error.
if(RICOCHET_USE_HDF5)
  set(workdir ${CMAKE_CURRENT_BINARY_DIR}/run/mpi_cross_rank_contacts)
  file(MAKE_DIRECTORY ${workdir})
  add_test(NAME mpi.cross_rank_contacts
           COMMAND ${RICOCHET_PYTHON} ${CMAKE_CURRENT_SOURCE_DIR}/mpi/check_cross_rank_contacts.py
                   $<TARGET_FILE:ricochet> ${workdir} ${MPIEXEC_EXECUTABLE} ${MPIEXEC_PREFLAGS}
           WORKING_DIRECTORY ${workdir})
  set_tests_properties(mpi.cross_rank_contacts PROPERTIES LABELS "mpi;regression"
                       ENVIRONMENT "${RICOCHET_TEST_ENV}" TIMEOUT 600)
endif()

# A large gas on 3 x 1 and 2 x 2 bricks against one rank, bit for bit, counters included:
# 100,000 spheres over 0.25 s, which met two defects the small gases never did (an impact
# timed apart, wall impacts counted twice; docs/architecture.md). About 70 s: label slow.
if(RICOCHET_USE_HDF5)
  set(workdir ${CMAKE_CURRENT_BINARY_DIR}/run/mpi_large_gas_bricks)
  file(MAKE_DIRECTORY ${workdir})
  add_test(NAME mpi.large_gas_bricks
           COMMAND ${RICOCHET_PYTHON} ${CMAKE_CURRENT_SOURCE_DIR}/mpi/check_large_gas_bricks.py
                   $<TARGET_FILE:ricochet> ${workdir} ${MPIEXEC_EXECUTABLE} ${MPIEXEC_PREFLAGS}
           WORKING_DIRECTORY ${workdir})
  set_tests_properties(mpi.large_gas_bricks PROPERTIES LABELS "mpi;regression;slow"
                       ENVIRONMENT "${RICOCHET_TEST_ENV}" TIMEOUT 900)
endif()
