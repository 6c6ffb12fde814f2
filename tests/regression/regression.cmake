# Regression cases that run the ricochet program on decks (included from tests/CMakeLists.txt).
set(RICOCHET_REGRESSION_DIR ${CMAKE_CURRENT_SOURCE_DIR}/regression)

# Every deck shipped in input/ validates.
file(GLOB shipped_decks CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/input/*.nml ${PROJECT_SOURCE_DIR}/input/validation/*.nml)
foreach(deck IN LISTS shipped_decks)
  get_filename_component(name ${deck} NAME_WE)
  add_test(NAME regression.check_deck.${name} COMMAND ricochet --check ${deck})
  set_tests_properties(regression.check_deck.${name} PROPERTIES LABELS regression)
endforeach()

# The resting-contact decks are what tools/bench_resting.py writes, so that they stay the
# scenes PyBullet and MuJoCo run there (needs only numpy).
add_test(NAME regression.resting_decks_match
         COMMAND ${RICOCHET_PYTHON} ${PROJECT_SOURCE_DIR}/tools/bench_resting.py --check-decks)
set_tests_properties(regression.resting_decks_match PROPERTIES LABELS regression TIMEOUT 60)

function(ricochet_python_case name script)
  set(workdir ${CMAKE_CURRENT_BINARY_DIR}/run/regression_${name})
  file(MAKE_DIRECTORY ${workdir})
  add_test(NAME regression.${name}
           COMMAND ${RICOCHET_PYTHON} ${RICOCHET_REGRESSION_DIR}/${script} ${ARGN}
           WORKING_DIRECTORY ${workdir})
  set_tests_properties(regression.${name} PROPERTIES LABELS "regression" ENVIRONMENT "${RICOCHET_TEST_ENV}"
                       TIMEOUT 600)
endfunction()

if(RICOCHET_USE_HDF5)
  # Stress (issue 19): a generated 10^6-triangle torus (binary STL) loads and runs one step
  # in under 10 s and 1 GB; the mesh is written in the case's folder, not committed.
  ricochet_python_case(mesh_stress_1m check_mesh_stress.py $<TARGET_FILE:ricochet>
                       ${CMAKE_CURRENT_BINARY_DIR}/run/regression_mesh_stress_1m)
  set_tests_properties(regression.mesh_stress_1m PROPERTIES LABELS "regression;stress" TIMEOUT 120)
  ricochet_python_case(free_fall check_free_fall.py $<TARGET_FILE:ricochet>
                       ${PROJECT_SOURCE_DIR}/input/validation/free_fall.nml ${CMAKE_CURRENT_BINARY_DIR}/run/regression_free_fall)
  ricochet_python_case(restart_bitwise check_restart.py $<TARGET_FILE:ricochet>
                       ${PROJECT_SOURCE_DIR}/input/validation/free_fall.nml ${CMAKE_CURRENT_BINARY_DIR}/run/regression_restart_bitwise)
  ricochet_python_case(restart_bitwise_pile check_restart.py $<TARGET_FILE:ricochet>
                       ${PROJECT_SOURCE_DIR}/input/validation/restart_pile.nml ${CMAKE_CURRENT_BINARY_DIR}/run/regression_restart_bitwise_pile)
  ricochet_python_case(restart_refusals check_restart_refusals.py $<TARGET_FILE:ricochet>
                       ${CMAKE_CURRENT_BINARY_DIR}/run/regression_restart_refusals ${PROJECT_SOURCE_DIR}/tests/data/meshes)
  ricochet_python_case(restart_bitwise_newmark check_restart.py $<TARGET_FILE:ricochet>
                       ${PROJECT_SOURCE_DIR}/input/validation/free_fall.nml ${CMAKE_CURRENT_BINARY_DIR}/run/regression_restart_bitwise_newmark newmark)
  # A full disk (a file-size limit) ends a run with one error line, no .tmp, valid indexes.
  ricochet_python_case(disk_full check_disk_full.py $<TARGET_FILE:ricochet>
                       ${CMAKE_CURRENT_BINARY_DIR}/run/regression_disk_full)
  # The local loop's livelock at one time is fixed: a checkpoint whose restart hit it
  # (tests/data/stall) completes, its repeated impacts held.
  ricochet_python_case(stall_guard check_stall_guard.py $<TARGET_FILE:ricochet>
                       ${PROJECT_SOURCE_DIR}/tests/data/stall ${CMAKE_CURRENT_BINARY_DIR}/run/regression_stall_guard)
  # SIGTERM, SIGINT and &run wall_limit stop a run with a checkpoint it continues from.
  ricochet_python_case(stop_and_continue check_stop.py $<TARGET_FILE:ricochet>
                       ${CMAKE_CURRENT_BINARY_DIR}/run/regression_stop_and_continue)
  ricochet_python_case(bouncing_ball check_bouncing_ball.py $<TARGET_FILE:ricochet>
                       ${PROJECT_SOURCE_DIR}/input/validation/bouncing_ball.nml ${CMAKE_CURRENT_BINARY_DIR}/run/regression_bouncing_ball)
  foreach(pair cradle:newtons_cradle two_three:cradle_two_into_three billiards:billiards_break
               tunnelling:tunnelling cube_drop:cube_drop spinning_elastic:spinning_cubes_edge
               spinning_inelastic:spinning_cubes_vertex)
    string(REPLACE ":" ";" pair ${pair})
    list(GET pair 0 case)
    list(GET pair 1 deck)
    ricochet_python_case(${deck} check_collisions.py ${case} $<TARGET_FILE:ricochet>
                         ${PROJECT_SOURCE_DIR}/input/validation/${deck}.nml ${CMAKE_CURRENT_BINARY_DIR}/run/regression_${deck})
  endforeach()
  foreach(case incline_slide incline_stick sliding_stop rolling_sphere box_on_box ball_rest sleep_wake correction)
    set(deck ${case})
    if(case STREQUAL ball_rest)
      set(deck bouncing_ball_rest)
    elseif(case STREQUAL correction)
      set(deck distance_correction)
    endif()
    ricochet_python_case(${case} check_resting.py ${case} $<TARGET_FILE:ricochet>
                         ${PROJECT_SOURCE_DIR}/input/validation/${deck}.nml ${CMAKE_CURRENT_BINARY_DIR}/run/regression_${case})
  endforeach()
  foreach(pair stack:stack_10_cubes pyramid:pyramid_15 pile_small:pile_8_cubes)
    string(REPLACE ":" ";" pair ${pair})
    list(GET pair 0 case)
    list(GET pair 1 deck)
    ricochet_python_case(${case} check_resting.py ${case} $<TARGET_FILE:ricochet>
                         ${PROJECT_SOURCE_DIR}/input/validation/${deck}.nml ${CMAKE_CURRENT_BINARY_DIR}/run/regression_${case})
  endforeach()
  ricochet_python_case(demo check_resting.py demo $<TARGET_FILE:ricochet>
                       ${PROJECT_SOURCE_DIR}/input/demo.nml ${CMAKE_CURRENT_BINARY_DIR}/run/regression_demo)
  # Issue 6's piles (local loop, two at a time): 1000 cubes and 1000 tetrahedra (2.5 min each),
  # 200 L-prisms (40 s)
  foreach(kind cubes tetrahedra l_shapes)
    ricochet_python_case(pile_${kind} check_resting.py pile $<TARGET_FILE:ricochet>
                         ${PROJECT_SOURCE_DIR}/input/validation/pile_${kind}.nml ${CMAKE_CURRENT_BINARY_DIR}/run/regression_pile_${kind})
    set_tests_properties(regression.pile_${kind} PROPERTIES LABELS "regression;slow")
  endforeach()
  # (the pyramid and the 8-cube pile took 23 s and 27 s in the global loop, 1 s each in the
  # local one: no longer labelled slow)
  ricochet_python_case(tori_chain check_collisions.py tori_chain $<TARGET_FILE:ricochet>
                       ${PROJECT_SOURCE_DIR}/input/validation/tori_chain.nml ${CMAKE_CURRENT_BINARY_DIR}/run/regression_tori_chain)
  ricochet_python_case(bouncing_mesh_ball check_bouncing_ball.py $<TARGET_FILE:ricochet>
                       ${PROJECT_SOURCE_DIR}/input/validation/bouncing_mesh_ball.nml ${CMAKE_CURRENT_BINARY_DIR}/run/regression_bouncing_mesh_ball
                       ${PROJECT_SOURCE_DIR}/input/meshes/icosphere_face_down.obj)
  ricochet_python_case(free_rotation_deck check_free_rotation.py $<TARGET_FILE:ricochet>
                       ${CMAKE_CURRENT_BINARY_DIR}/run/regression_free_rotation_deck ${RICOCHET_TEST_DATA}/free_rotation_I123.csv)
  # The local event loop against the global one on gases of 200 spheres and 200 cubes (5 s)
  ricochet_python_case(local_events check_local_events.py $<TARGET_FILE:ricochet>
                       ${CMAKE_CURRENT_BINARY_DIR}/run/regression_local_events)
  # Elastic (e = 1) ball lattices on a floor, both loops: the 10 x 10 deck that stalled the
  # time of contact ("collision loop stalled"), and 900 balls landing at once that conserve
  # energy to 1e-12 (check_elastic_lattice.py; 8 s)
  ricochet_python_case(elastic_lattice check_elastic_lattice.py $<TARGET_FILE:ricochet>
                       ${CMAKE_CURRENT_BINARY_DIR}/run/regression_elastic_lattice)
  # A chain A -> B -> C (a stale bound would tunnel) and a free cluster never stepped (2 s)
  ricochet_python_case(local_cases check_local_cases.py $<TARGET_FILE:ricochet>
                       ${CMAKE_CURRENT_BINARY_DIR}/run/regression_local_cases)
  # Materials per pair: two balls of different e on one floor (each its own apex ratio e^2),
  # two cubes of different mu, under each restitution_rule and friction_rule (4 s)
  ricochet_python_case(materials check_materials.py $<TARGET_FILE:ricochet>
                       ${CMAKE_CURRENT_BINARY_DIR}/run/regression_materials)
  # The certificate audit (&integrator audit_certificates): after every event every pair with
  # a moving body must hold a current certificate that reaches the next event; a hole is an
  # error naming the pair, so the run's exit status is the test (tests/data/audit/).
  foreach(case pile_8_cubes_audit pile_64_cubes_audit)
    set(workdir ${CMAKE_CURRENT_BINARY_DIR}/run/regression_${case})
    file(MAKE_DIRECTORY ${workdir})
    add_test(NAME regression.${case}
             COMMAND $<TARGET_FILE:ricochet> ${RICOCHET_TEST_DATA}/audit/${case}.nml --output-dir ${workdir}/out
             WORKING_DIRECTORY ${workdir})
    set_tests_properties(regression.${case} PROPERTIES LABELS "regression;stress" ENVIRONMENT "${RICOCHET_TEST_ENV}"
                         TIMEOUT 300)
  endforeach()
  # Stress cases (label stress, each < 2 s here): mass ratio 1e6, a cube spinning at
  # 1e4 rad/s landing, bodies from 1e-6 m to 1e4 m (check_stress.py)
  foreach(case mass_ratio spinning)
    ricochet_python_case(stress_${case} check_stress.py ${case} $<TARGET_FILE:ricochet>
                         ${CMAKE_CURRENT_BINARY_DIR}/run/regression_stress_${case})
    set_tests_properties(regression.stress_${case} PROPERTIES LABELS "regression;stress" TIMEOUT 120)
  endforeach()
  ricochet_python_case(stress_scales check_stress.py scales $<TARGET_FILE:ricochet>
                       ${CMAKE_CURRENT_BINARY_DIR}/run/regression_stress_scales global)
  set_tests_properties(regression.stress_scales PROPERTIES LABELS "regression;stress" TIMEOUT 120)
  # the same with the local event loop (the default): its grid once lost the 1e4 m body
  # (box coordinates past 2^31, see check_stress.py and unit.test_cell_grid)
  ricochet_python_case(stress_scales_local check_stress.py scales $<TARGET_FILE:ricochet>
                       ${CMAKE_CURRENT_BINARY_DIR}/run/regression_stress_scales_local local)
  set_tests_properties(regression.stress_scales_local PROPERTIES LABELS "regression;stress" TIMEOUT 120)
  # (runs a few valid decks too, which write output)
  ricochet_python_case(input_errors check_errors.py $<TARGET_FILE:ricochet>
                       ${CMAKE_CURRENT_BINARY_DIR}/run/regression_input_errors ${RICOCHET_TEST_DATA})
endif()
