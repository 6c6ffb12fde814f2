!> deck_reader: a full deck read with every value checked, defaults filled in, the effective
!> deck read back to an identical deck_t, and bad decks each rejected with a message naming
!> the deck, the line, the group (the &body by index and name) and the variable. The
!> built-in tetrahedron, torus and L prism are also built (body_builder), to check that each
!> deck value reaches the right builder argument.
!> Decks are written into the test's run folder. Values are compared exactly: a decimal
!> literal read twice gives the same double, and write_effective_deck writes the shortest
!> text that reads back exactly, so any difference is a bug, not round-off.
program test_deck_reader
  use kinds, only: dp
  use constants, only: pi
  use error_status, only: error_t, ERR_IO
  use input_config, only: deck_t, body_spec_t
  use deck_reader, only: read_deck, write_effective_deck, DECK_AUTO
  use shape, only: shape_library_t
  use body_builder, only: build_shapes
  use assertions
  implicit none
  character(len=4096) :: cwd_buffer
  character(len=:), allocatable :: cwd
  character(len=120) :: f5(5)

  call execute_command_line('mkdir -p sub/meshes', wait=.true.)
  call write_lines('sub/meshes/cube.obj', [character(len=40) :: 'v 0 0 0'])
  call getcwd_portable(cwd_buffer)
  cwd = trim(cwd_buffer)

  call test_full_deck()
  call test_defaults()
  call test_round_trip()
  call test_new_shapes_and_materials()
  call test_bad_decks()
  call test_syntax_edges()
  call test_finish()

contains

  subroutine getcwd_portable(folder)
    character(len=*), intent(out) :: folder
    integer :: unit
    ! The shell's idea of the folder: the reader must store the same absolute paths.
    call execute_command_line('pwd > cwd.txt', wait=.true.)
    open (newunit=unit, file='cwd.txt', action='read')
    read (unit, '(a)') folder
    close (unit)
  end subroutine getcwd_portable

  subroutine write_lines(path, lines)
    character(len=*), intent(in) :: path, lines(:)
    integer :: unit, i
    open (newunit=unit, file=path, action='write', status='replace')
    do i = 1, size(lines)
      write (unit, '(a)') trim(lines(i))
    end do
    close (unit)
  end subroutine write_lines

  !> Every group, comments, FDS-style trailing commas, a subscript, a repeat count, two
  !> groups on one line, a mesh found relative to the deck's folder.
  subroutine test_full_deck()
    type(deck_t) :: deck
    type(error_t) :: err
    call write_lines('sub/full.nml', [character(len=100) :: &
      '! a full deck', &                                                          ! 1
      '&run title = ''Full "deck", it''''s'', t_end = 2.5, dt_max = 1e-3,', &      ! 2
      '     gravity(3) = -9.81 /  ! only z', &                                    ! 3
      '&integrator newmark_beta = 0.3, newmark_gamma = 0.55, rotation = ''EXACT'',', &
      '  rotation_tolerance = 1d-12, rotation_max_iterations = 20, events = '' Global'' /', &   ! 5
      '&contact restitution = 0.8, friction = 0.3, min_separation = 1e-5 / &output dir = ''out/a'',', &
      '  interval = 0.05, checkpoint_interval = 1.0, progress_interval = 2 /', &   ! 7
      '&BODY name = ''ground'', shape = ''box'', size = 10, 10, 1, fixed = .true.,', &
      '  position = 0, 0, -0.5 /', &                                              ! 9
      '&body name = ''pins'', shape = ''cylinder'', radius = 0.05, size(3) = 0.4, segments = 16,', &
      '  mass = 0.2, position = 1, 2, 3, velocity = 3*0.5, angular_velocity = 0, 0, 1,', &
      '  copies = 4, 3, 2, spacing = 0.2, 0.3, 0.5, seed = 42,', &                 ! 12
      '  jitter_position = 1e-3, jitter_angle = 0.1, jitter_velocity = 0.01 /', &  ! 13
      '&body shape = ''mesh'', mesh_file = ''meshes/cube.obj'', scale = 0.01, density = 2700,', &
      '  orientation = 0.7071067811865476, 0, 0, 0.7071067811865476 /'])          ! 15
    call read_deck('sub/full.nml', deck, err)
    call check(err%ok(), 'full deck reads: '//message(err))
    if (err%failed()) return
    call check(deck%path == 'sub/full.nml', 'deck path as given')
    call check(deck%folder == cwd//'/sub', 'deck folder is absolute: '//deck%folder)
    call check(deck%run%title == 'Full "deck", it''s', 'title with quotes: '//trim(deck%run%title))
    call check(deck%run%t_end == 2.5_dp .and. deck%run%dt_max == 1.0e-3_dp, 't_end, dt_max')
    call check(all(deck%run%gravity == [0.0_dp, 0.0_dp, -9.81_dp]), 'gravity(3) alone, others default 0')
    call check(deck%integrator%newmark_beta == 0.3_dp .and. deck%integrator%newmark_gamma == 0.55_dp, 'newmark')
    call check(deck%integrator%rotation == 'exact', 'rotation folded to lower case')
    call check(deck%integrator%rotation_tolerance == 1.0e-12_dp, 'rotation_tolerance (d exponent)')
    call check(deck%integrator%rotation_max_iterations == 20, 'rotation_max_iterations')
    call check(deck%integrator%events == 'global', 'events: leading blank dropped, folded to lower case')
    call check(deck%contact%restitution == 0.8_dp .and. deck%contact%friction == 0.3_dp .and. &
               deck%contact%min_separation == 1.0e-5_dp, 'contact')
    call check(deck%output%dir == cwd//'/sub/out/a', 'output dir resolved: '//trim(deck%output%dir))
    call check(deck%output%interval == 0.05_dp .and. deck%output%checkpoint_interval == 1.0_dp .and. &
               deck%output%progress_interval == 2.0_dp, 'output intervals')
    call check(deck%n_bodies == 3 .and. size(deck%bodies) == 3, 'three bodies')
    if (deck%n_bodies /= 3) return
    associate (b => deck%bodies(1))
      call check(b%name == 'ground' .and. b%shape == 'box' .and. b%fixed, 'ground: name, shape, fixed')
      call check(all(b%size == [10.0_dp, 10.0_dp, 1.0_dp]), 'ground size')
      call check(all(b%position == [0.0_dp, 0.0_dp, -0.5_dp]), 'ground position')
      call check(b%density == -1.0_dp .and. b%mass == -1.0_dp, 'fixed body: no density, no mass')
      call check(b%line == 8, 'ground line 8: '//str_i(b%line))
    end associate
    associate (b => deck%bodies(2))
      call check(b%name == 'pins' .and. b%shape == 'cylinder', 'pins: name, shape')
      call check(b%radius == 0.05_dp .and. b%size(3) == 0.4_dp .and. all(b%size(1:2) == -1.0_dp), &
                 'cylinder radius and length size(3)')
      call check(b%segments == 16 .and. b%mass == 0.2_dp .and. b%density == -1.0_dp, 'segments, mass')
      call check(all(b%position == [1.0_dp, 2.0_dp, 3.0_dp]), 'pins position')
      call check(all(b%velocity == 0.5_dp), 'repeat count 3*0.5')
      call check(all(b%angular_velocity == [0.0_dp, 0.0_dp, 1.0_dp]), 'angular velocity')
      call check(all(b%copies == [4, 3, 2]) .and. all(b%spacing == [0.2_dp, 0.3_dp, 0.5_dp]), 'lattice')
      call check(b%seed == 42 .and. b%jitter_position == 1.0e-3_dp .and. b%jitter_angle == 0.1_dp .and. &
                 b%jitter_velocity == 0.01_dp, 'jitter')
      call check(all(b%orientation == [1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp]), 'default orientation')
      call check(b%line == 10, 'pins line 10')
    end associate
    associate (b => deck%bodies(3))
      call check(b%name == 'body3', 'default name body<index>: '//trim(b%name))
      call check(b%mesh_file == cwd//'/sub/meshes/cube.obj', 'mesh_file resolved: '//trim(b%mesh_file))
      call check(b%scale == 0.01_dp .and. b%density == 2700.0_dp, 'scale, density')
      ! 0.7071067811865476 is 1/sqrt(2) to 16 digits: the norm is within a few ulps of 1, so the
      ! reader keeps it; its components agree with 1/sqrt(2) to 1 ulp (rtol 2.3e-16).
      call check_close_array(b%orientation, [sqrt(0.5_dp), 0.0_dp, 0.0_dp, sqrt(0.5_dp)], 2.3e-16_dp, &
                             'orientation read')
      call check(abs(norm2(b%orientation) - 1.0_dp) <= 4.0_dp*epsilon(1.0_dp), 'orientation unit to 4 eps')
    end associate
  end subroutine test_full_deck

  subroutine test_defaults()
    type(deck_t) :: deck
    type(error_t) :: err
    call write_lines('minimal.nml', [character(len=100) :: &
      '&run t_end = 1, dt_max = 0.1 /', &
      '&body shape = ''sphere'', radius = 0.5, density = 1000, orientation = 2, 0, 0, 0 /'])
    call read_deck('minimal.nml', deck, err)
    call check(err%failed(), 'orientation of norm 2 is rejected')
    call write_lines('minimal.nml', [character(len=100) :: &
      '&run t_end = 1, dt_max = 0.1 /', &
      '&body shape = ''Sphere'', radius = 0.5, density = 1000, orientation = 1.0000001, 0, 0, 0 /'])
    call err%clear()
    call read_deck('minimal.nml', deck, err)
    call check(err%ok(), 'minimal deck reads: '//message(err))
    if (err%failed()) return
    call check(deck%folder == cwd, 'folder of a bare file name is the current folder')
    call check(deck%run%title == 'ricochet run' .and. all(deck%run%gravity == 0.0_dp), 'run defaults')
    call check(deck%integrator%newmark_beta == 0.25_dp .and. deck%integrator%newmark_gamma == 0.5_dp .and. &
               deck%integrator%rotation_tolerance == 1.0e-14_dp .and. &
               deck%integrator%rotation_max_iterations == 50 .and. deck%integrator%rotation == 'exact' .and. &
               deck%integrator%events == 'auto', 'integrator defaults')
    call check(deck%contact%restitution == 0.5_dp .and. deck%contact%friction == 0.0_dp .and. &
               deck%contact%min_separation == DECK_AUTO .and. deck%contact%rest_speed == DECK_AUTO, &
               'contact defaults (min_separation, rest_speed auto)')
    call check(deck%output%dir == cwd//'/output', 'output dir default resolved: '//trim(deck%output%dir))
    call check(deck%output%interval == DECK_AUTO .and. deck%output%checkpoint_interval == 0.0_dp .and. &
               deck%output%progress_interval == 10.0_dp, 'output defaults')
    associate (b => deck%bodies(1))
      call check(b%name == 'body1' .and. b%shape == 'sphere', 'body name default, shape folded')
      call check(.not. b%fixed .and. all(b%copies == 1) .and. all(b%spacing == 0.0_dp) .and. b%seed == 0 .and. &
                 b%jitter_position == 0.0_dp .and. b%jitter_angle == 0.0_dp .and. b%jitter_velocity == 0.0_dp, &
                 'body defaults')
      call check(all(b%position == 0.0_dp) .and. all(b%velocity == 0.0_dp) .and. &
                 all(b%angular_velocity == 0.0_dp) .and. b%mass == -1.0_dp, 'motion defaults')
      ! 1.0000001 is within unit_quaternion_tolerance (1e-6) of 1: renormalised to exactly 1.
      call check(all(b%orientation == [1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp]), 'orientation renormalised')
      call check(b%restitution == DECK_AUTO .and. b%friction == DECK_AUTO, 'material defaults: -1, &contact''s')
      call check(b%segments == 32 .and. b%tube_segments == 16 .and. b%minor_radius == -1.0_dp .and. &
                 b%thickness == -1.0_dp, 'shape defaults of other shapes')
    end associate
  end subroutine test_defaults

  !> read -> write_effective_deck -> read gives the same deck_t; writing again gives the same text.
  subroutine test_round_trip()
    type(deck_t) :: first, second
    type(error_t) :: err
    integer :: unit, k
    call read_deck('sub/full.nml', first, err)
    call check(err%ok(), 'round trip: full deck reads')
    if (err%failed()) return
    open (newunit=unit, file='effective.nml', action='write', status='replace')
    call write_effective_deck(first, unit)
    close (unit)
    call read_deck('effective.nml', second, err)
    call check(err%ok(), 'effective deck reads back: '//message(err))
    if (err%failed()) return
    call check(first%run%title == second%run%title .and. first%run%t_end == second%run%t_end .and. &
               first%run%dt_max == second%run%dt_max .and. all(first%run%gravity == second%run%gravity), &
               'round trip &run')
    call check(first%integrator%newmark_beta == second%integrator%newmark_beta .and. &
               first%integrator%newmark_gamma == second%integrator%newmark_gamma .and. &
               first%integrator%rotation_tolerance == second%integrator%rotation_tolerance .and. &
               first%integrator%rotation_max_iterations == second%integrator%rotation_max_iterations .and. &
               first%integrator%rotation == second%integrator%rotation .and. &
               first%integrator%events == second%integrator%events, 'round trip &integrator')
    call check(first%contact%restitution == second%contact%restitution .and. &
               first%contact%friction == second%contact%friction .and. &
               first%contact%min_separation == second%contact%min_separation .and. &
               first%contact%rest_speed == second%contact%rest_speed, 'round trip &contact')
    call check(first%output%dir == second%output%dir .and. first%output%interval == second%output%interval .and. &
               first%output%checkpoint_interval == second%output%checkpoint_interval .and. &
               first%output%progress_interval == second%output%progress_interval, 'round trip &output')
    call check(first%n_bodies == second%n_bodies, 'round trip body count')
    if (first%n_bodies /= second%n_bodies) return
    do k = 1, first%n_bodies
      call check(same_body(first%bodies(k), second%bodies(k)), 'round trip &body #'//str_i(k))
    end do
    ! Auto values and defaults survive too (the minimal deck).
    call read_deck('minimal.nml', first, err)
    call check(err%ok(), 'round trip: minimal deck reads')
    open (newunit=unit, file='effective_minimal.nml', action='write', status='replace')
    call write_effective_deck(first, unit)
    close (unit)
    call read_deck('effective_minimal.nml', second, err)
    call check(err%ok(), 'effective minimal deck reads back: '//message(err))
    if (err%failed()) return
    call check(second%contact%min_separation == DECK_AUTO .and. second%output%interval == DECK_AUTO .and. &
               second%contact%rest_speed == DECK_AUTO, 'auto values read back as auto')
    call check(same_body(first%bodies(1), second%bodies(1)), 'round trip minimal body')
    ! A second generation writes the same text as the first (paths are absolute).
    open (newunit=unit, file='effective_minimal2.nml', action='write', status='replace')
    call write_effective_deck(second, unit)
    close (unit)
    call check(same_text_after_header('effective_minimal.nml', 'effective_minimal2.nml'), &
               'effective deck of the effective deck is the same text')
  end subroutine test_round_trip

  !> The tetrahedron, torus and L prism, per-body materials (a fixed floor's too) and
  !> rest_speed: read, round-tripped through the effective deck, and built into shapes whose
  !> volumes match the closed forms of the meshes the builders make.
  subroutine test_new_shapes_and_materials()
    type(deck_t) :: first, second
    type(error_t) :: err
    type(shape_library_t) :: shapes
    integer, allocatable :: shape_of_group(:)
    integer :: unit, k
    real(dp) :: expected
    ! Volumes are sums over at most 576 faces of O(1) terms: 1e-12 relative leaves ~4000 ulps.
    real(dp), parameter :: tol = 1.0e-12_dp
    call write_lines('shapes.nml', [character(len=100) :: &
      '&run t_end = 1, dt_max = 0.01, gravity = 0, 0, -9.81 /', &                   ! 1
      '&contact restitution = 0.7, friction = 0.4, rest_speed = 0.05 /', &           ! 2
      '&body name = ''floor'', shape = ''box'', size = 4, 4, 0.2, fixed = .true.,', &  ! 3
      '  restitution = 0.2, friction = 0 /', &                                        ! 4
      '&body name = ''tet'', shape = ''TetraHedron'', size(1) = 0.3, density = 500,', & ! 5
      '  restitution = 1, position = 0, 0, 1 /', &                                    ! 6
      '&body name = ''ring'', shape = ''torus'', radius = 0.5, minor_radius = 0.1,', &  ! 7
      '  segments = 24, mass = 2, friction = 0.9, position = 2, 0, 1 /', &            ! 8
      '&body name = ''ell'', shape = ''l_prism'', size = 0.4, 0.3, 0.1,', &             ! 9
      '  thickness = 0.05, density = 1000, position = -2, 0, 1, tube_segments = 5 /'])  ! 10: not a torus
    call read_deck('shapes.nml', first, err)
    call check(err%failed(), 'tube_segments on an l_prism is refused')
    f5(1) = 'shapes.nml:10:'
    f5(2) = '&body #4 ''ell'''
    f5(3) = 'tube_segments does not apply to shape ''l_prism'''
    call check_error(err%code, message(err), f5(1:3), 'tube_segments on an l_prism')
    call write_lines('shapes.nml', [character(len=100) :: &
      '&run t_end = 1, dt_max = 0.01, gravity = 0, 0, -9.81 /', &
      '&contact restitution = 0.7, friction = 0.4, rest_speed = 0.05 /', &
      '&body name = ''floor'', shape = ''box'', size = 4, 4, 0.2, fixed = .true.,', &
      '  restitution = 0.2, friction = 0 /', &
      '&body name = ''tet'', shape = ''TetraHedron'', size(1) = 0.3, density = 500,', &
      '  restitution = 1, position = 0, 0, 1 /', &
      '&body name = ''ring'', shape = ''torus'', radius = 0.5, minor_radius = 0.1,', &
      '  segments = 24, mass = 2, friction = 0.9, position = 2, 0, 1 /', &
      '&body name = ''ell'', shape = ''l_prism'', size = 0.4, 0.3, 0.1,', &
      '  thickness = 0.05, density = 1000, position = -2, 0, 1 /'])
    call err%clear()
    call read_deck('shapes.nml', first, err)
    call check(err%ok(), 'new shapes deck reads: '//message(err))
    if (err%failed()) return
    call check(first%contact%rest_speed == 0.05_dp, 'rest_speed read')
    call check(first%n_bodies == 4, 'four bodies')
    if (first%n_bodies /= 4) return
    associate (b => first%bodies(1))
      call check(b%fixed .and. b%restitution == 0.2_dp .and. b%friction == 0.0_dp, 'a fixed floor has a material')
    end associate
    associate (b => first%bodies(2))
      call check(b%shape == 'tetrahedron' .and. b%size(1) == 0.3_dp .and. all(b%size(2:3) == -1.0_dp), &
                 'tetrahedron: shape folded, edge size(1)')
      call check(b%restitution == 1.0_dp .and. b%friction == DECK_AUTO, 'tetrahedron: own e, &contact''s mu')
    end associate
    associate (b => first%bodies(3))
      call check(b%shape == 'torus' .and. b%radius == 0.5_dp .and. b%minor_radius == 0.1_dp, 'torus radii')
      call check(b%segments == 24 .and. b%tube_segments == 16, 'torus segments given, tube_segments default 16')
      call check(b%restitution == DECK_AUTO .and. b%friction == 0.9_dp, 'torus: &contact''s e, own mu')
    end associate
    associate (b => first%bodies(4))
      call check(b%shape == 'l_prism' .and. all(b%size == [0.4_dp, 0.3_dp, 0.1_dp]) .and. b%thickness == 0.05_dp, &
                 'l_prism size and thickness')
    end associate

    open (newunit=unit, file='shapes_effective.nml', action='write', status='replace')
    call write_effective_deck(first, unit)
    close (unit)
    call read_deck('shapes_effective.nml', second, err)
    call check(err%ok(), 'new shapes effective deck reads back: '//message(err))
    if (err%failed()) return
    call check(second%contact%rest_speed == first%contact%rest_speed, 'round trip rest_speed')
    call check(second%n_bodies == first%n_bodies, 'round trip new shapes: body count')
    if (second%n_bodies /= first%n_bodies) return
    do k = 1, first%n_bodies
      call check(same_body(first%bodies(k), second%bodies(k)), 'round trip new shapes &body #'//str_i(k))
    end do
    open (newunit=unit, file='shapes_effective2.nml', action='write', status='replace')
    call write_effective_deck(second, unit)
    close (unit)
    call check(same_text_after_header('shapes_effective.nml', 'shapes_effective2.nml'), &
               'new shapes: effective deck of the effective deck is the same text')

    call build_shapes(first, shapes, shape_of_group, err)
    call check(err%ok(), 'new shapes build: '//message(err))
    if (err%failed()) return
    call check(shapes%n_shapes == 4, 'four distinct shapes')
    associate (s => shapes%shapes(shape_of_group(2)))
      ! Regular tetrahedron of edge a: V = a^3/(6 sqrt 2).
      call check(s%mesh%n_faces == 4, 'tetrahedron: 4 faces')
      call check_close(s%volume, 0.3_dp**3/(6.0_dp*sqrt(2.0_dp)), tol, 'tetrahedron volume a^3/(6 sqrt 2)')
    end associate
    associate (s => shapes%shapes(shape_of_group(3)))
      ! Faceted torus (n segments around z, m around the tube): each wedge between meridians is
      ! swept linearly, with Jacobian rho sin(2 pi/n), so V = n sin(2 pi/n) R * (m/2) r^2 sin(2 pi/m)
      ! (Pappus with the polygon's area and the chord instead of the arc).
      call check(s%mesh%n_faces == 2*24*16 .and. s%mesh%n_nodes == 24*16, 'torus: 24 x 16 segments')
      call check(index(s%mesh%source, '24 x 16 segments') > 0, 'torus: segments around z, tube_segments around '// &
                 'the tube: '//s%mesh%source)
      expected = 24.0_dp*sin(2.0_dp*pi/24.0_dp)*0.5_dp*8.0_dp*0.1_dp**2*sin(2.0_dp*pi/16.0_dp)
      call check_close(s%volume, expected, tol, 'torus volume (faceted closed form)')
      call check(.not. s%convex, 'torus is not convex')
    end associate
    associate (s => shapes%shapes(shape_of_group(4)))
      ! L profile: x t + (y - t) t, extruded z.
      call check(s%mesh%n_faces == 20, 'l_prism: 20 faces')
      call check_close(s%volume, (0.4_dp*0.05_dp + (0.3_dp - 0.05_dp)*0.05_dp)*0.1_dp, tol, 'l_prism volume')
      call check(.not. s%convex, 'l_prism is not convex')
    end associate
  end subroutine test_new_shapes_and_materials

  logical function same_body(a, b)
    type(body_spec_t), intent(in) :: a, b
    same_body = a%name == b%name .and. a%shape == b%shape .and. a%radius == b%radius .and. &
                all(a%size == b%size) .and. a%segments == b%segments .and. a%mesh_file == b%mesh_file .and. &
                a%scale == b%scale .and. a%density == b%density .and. a%mass == b%mass .and. &
                all(a%position == b%position) .and. all(a%orientation == b%orientation) .and. &
                all(a%velocity == b%velocity) .and. all(a%angular_velocity == b%angular_velocity) .and. &
                (a%fixed .eqv. b%fixed) .and. all(a%copies == b%copies) .and. all(a%spacing == b%spacing) .and. &
                a%seed == b%seed .and. a%jitter_position == b%jitter_position .and. &
                a%jitter_angle == b%jitter_angle .and. a%jitter_velocity == b%jitter_velocity .and. &
                a%minor_radius == b%minor_radius .and. a%tube_segments == b%tube_segments .and. &
                a%thickness == b%thickness .and. all(a%inertia == b%inertia) .and. &
                a%restitution == b%restitution .and. a%friction == b%friction
  end function same_body

  !> Same lines, apart from the '! deck:' line that names the file.
  logical function same_text_after_header(path_a, path_b)
    character(len=*), intent(in) :: path_a, path_b
    character(len=2048) :: line_a, line_b
    integer :: unit_a, unit_b, ios_a, ios_b
    open (newunit=unit_a, file=path_a, action='read')
    open (newunit=unit_b, file=path_b, action='read')
    same_text_after_header = .true.
    do
      read (unit_a, '(a)', iostat=ios_a) line_a
      read (unit_b, '(a)', iostat=ios_b) line_b
      if (ios_a /= 0 .or. ios_b /= 0) then
        same_text_after_header = same_text_after_header .and. ios_a == ios_b
        exit
      end if
      if (line_a(1:8) == '! deck: ') cycle
      if (line_a /= line_b) same_text_after_header = .false.
    end do
    close (unit_a)
    close (unit_b)
  end function same_text_after_header

  !> Syntax corners: CR LF line ends, tabs, upper case, '!' and '/' inside quotes, a slash
  !> right after a value, an empty group, an empty deck, values continued on the next line,
  !> blanks inside subscripts.
  subroutine test_syntax_edges()
    type(deck_t) :: deck
    type(error_t) :: err
    integer :: unit
    character(len=*), parameter :: crlf = achar(13)//achar(10)
    open (newunit=unit, file='edges.nml', access='stream', form='unformatted', action='write', status='replace')
    write (unit) '&RUN T_END=3.0 DT_MAX=0.5/'//crlf, &
      '! title = ''x'''//crlf, &
      '&Output'//achar(9)//'dir = ''a!b/c'', interval'//achar(9)//'= 0.1 /'//crlf, &
      '&contact /'//crlf, &
      '&body shape = "box", size =', crlf, '  1.0', crlf, '  2.0 3.0 density=1 /', crlf, &
      '&body shape = ''box'', size(1 : 2) = 4 5, size( 3 ) = 6, mass = 1 /'
    close (unit)
    call read_deck('edges.nml', deck, err)
    call check(err%ok(), 'edges deck reads: '//message(err))
    if (err%failed()) return
    call check(deck%run%t_end == 3.0_dp .and. deck%run%dt_max == 0.5_dp, 'upper case names, slash after value')
    call check(deck%run%title == 'ricochet run', 'commented-out title ignored')
    call check(deck%output%dir == cwd//'/a!b/c', '! and / inside quotes kept: '//trim(deck%output%dir))
    call check(deck%output%interval == 0.1_dp, 'tab as blank')
    call check(deck%contact%restitution == 0.5_dp, 'empty group keeps defaults')
    call check(all(deck%bodies(1)%size == [1.0_dp, 2.0_dp, 3.0_dp]), 'values continued over lines')
    call check(all(deck%bodies(2)%size == [4.0_dp, 5.0_dp, 6.0_dp]), 'blanks inside subscripts')

    call write_lines('empty.nml', [character(len=1) :: ' '])
    call err%clear()
    call read_deck('empty.nml', deck, err)
    f5(1) = 'empty.nml: no &run group'
    call check_error(err%code, message(err), f5(1:1), 'empty deck')

    ! The shortest text that reads back: 0.1 + 0.2 is not 0.3 and must not be written so.
    call write_lines('digits.nml', [character(len=100) :: '&run t_end = 0.30000000000000004, dt_max = 0.1 /', &
      '&body shape = ''sphere'', radius = 1e-300, density = 1.7976931348623157e307 /'])
    call err%clear()
    call read_deck('digits.nml', deck, err)
    call check(err%ok(), 'digits deck reads: '//message(err))
    if (err%failed()) return
    open (newunit=unit, file='digits_effective.nml', action='write', status='replace')
    call write_effective_deck(deck, unit)
    close (unit)
    block
      type(deck_t) :: again
      call read_deck('digits_effective.nml', again, err)
      call check(err%ok(), 'digits effective deck reads: '//message(err))
      if (err%failed()) return
      call check(again%run%t_end == 0.1_dp + 0.2_dp, '0.1 + 0.2 survives the round trip')
      call check(again%bodies(1)%radius == 1.0e-300_dp .and. again%bodies(1)%density == 1.7976931348623157e307_dp, &
                 'extreme magnitudes survive the round trip')
    end block
  end subroutine test_syntax_edges

  !> Writes a bad deck, reads it, and checks the error holds every fragment.
  subroutine bad(name, lines, fragments)
    character(len=*), intent(in) :: name, lines(:), fragments(:)
    type(deck_t) :: deck
    type(error_t) :: err
    call write_lines(name, lines)
    call read_deck(name, deck, err)
    call check_error(err%code, message(err), fragments, 'bad deck '//name)
    print '(a)', message(err)   ! the log shows what a user would see
  end subroutine bad

  subroutine test_bad_decks()
    character(len=*), parameter :: run = '&run t_end = 1.0, dt_max = 0.01 /'
    character(len=*), parameter :: ball = '&body name = ''ball'', shape = ''sphere'', radius = 0.1, density = 1000 /'
    type(deck_t) :: deck
    type(error_t) :: err
    character(len=120) :: f(5)

    ! unknown variable, with its line inside a multi-line group and a suggestion
    call bad('bad_unknown_var.nml', [character(len=100) :: run, ball, &
      '&body name = ''rock'', shape = ''sphere'',', '  radus = 1, density = 3 /'], &
      [character(len=60) :: 'bad_unknown_var.nml:4:', '&body #2 ''rock''', 'unknown variable ''radus''', &
       'did you mean ''radius''?'])
    call bad('bad_group.nml', [character(len=100) :: run, '! comment', '&bdy shape = ''sphere'' /'], &
      [character(len=60) :: 'bad_group.nml:3:', 'unknown group ''&bdy''', 'did you mean ''&body''', '&run, &integrator'])
    call bad('bad_type_string.nml', [character(len=100) :: '&run dt_max = 0.1,', '  t_end = ''abc'' /', ball], &
      [character(len=60) :: 'bad_type_string.nml:2:', '&run:', 't_end needs a number', 'abc'])
    call bad('bad_type_word.nml', [character(len=100) :: '&run dt_max = 0.1, t_end = abc /', ball], &
      [character(len=60) :: 'bad_type_word.nml:1:', '&run:', 't_end needs a number, got ''abc'''])
    call bad('bad_no_t_end.nml', [character(len=100) :: ball, '&run dt_max = 0.1 /'], &
      [character(len=60) :: 'bad_no_t_end.nml:2:', '&run:', 't_end is required'])
    call bad('bad_t_end.nml', [character(len=100) :: '&run', 't_end = 0, dt_max = 0.1 /', ball], &
      [character(len=60) :: 'bad_t_end.nml:2:', '&run:', 't_end must be > 0'])
    call bad('bad_nan.nml', [character(len=100) :: '&run t_end = 1, dt_max = 0.1,', ' gravity = 0, 0, NaN /', ball], &
      [character(len=60) :: 'bad_nan.nml:2:', '&run:', 'gravity must be a finite number', 'NaN'])
    call bad('bad_inf.nml', [character(len=100) :: run, ball, &
      '&body name = ''rock'', shape = ''sphere'', radius = 0.1, mass = -Infinity /'], &
      [character(len=60) :: 'bad_inf.nml:3:', '&body #2 ''rock''', 'mass must be a finite number'])
    call bad('bad_overflow.nml', [character(len=100) :: '&run t_end = 1e400, dt_max = 0.1 /', ball], &
      [character(len=60) :: 'bad_overflow.nml:1:', '&run:', 't_end = 1e400 is out of range'])
    call bad('bad_mass.nml', [character(len=100) :: run, ball, &
      '&body name = ''rock'', shape = ''sphere'', radius = 0.1, mass = -2 /'], &
      [character(len=60) :: 'bad_mass.nml:3:', '&body #2 ''rock''', 'mass must be > 0 kg'])
    call bad('bad_mass_density.nml', [character(len=100) :: run, '&body shape = ''sphere'', radius = 0.1,', &
      '  density = 1000,', '  mass = 2 /'], &
      [character(len=60) :: 'bad_mass_density.nml:4:', '&body #1 ''body1''', 'density or mass, not both'])
    call bad('bad_no_mass.nml', [character(len=100) :: run, '&body shape = ''sphere'', radius = 0.1 /'], &
      [character(len=60) :: 'bad_no_mass.nml:2:', '&body #1 ''body1''', 'give density [kg/m^3] or mass'])
    call bad('bad_radius.nml', [character(len=100) :: run, ball, &
      '&body name = ''rock'', shape = ''sphere'', density = 1,', '  radius = 0.0 /'], &
      [character(len=60) :: 'bad_radius.nml:4:', '&body #2 ''rock''', 'radius must be > 0 m'])
    call bad('bad_quaternion.nml', [character(len=100) :: run, &
      '&body name = ''q'', shape = ''sphere'', radius = 1, density = 1,', '  orientation = 1, 0.1, 0, 0 /'], &
      [character(len=60) :: 'bad_quaternion.nml:3:', '&body #1 ''q''', 'orientation must be a unit quaternion'])
    call bad('bad_restitution.nml', [character(len=100) :: run, '&contact friction = 0.1,', &
      ' restitution = 1.5 /', ball], &
      [character(len=60) :: 'bad_restitution.nml:3:', '&contact:', 'restitution must be in [0, 1]', '1.5'])
    call bad('bad_mesh_file.nml', [character(len=100) :: run, &
      '&body name = ''bunny'', shape = ''mesh'', mesh_file = ''missing.obj'', density = 1 /'], &
      [character(len=60) :: 'bad_mesh_file.nml:2:', '&body #1 ''bunny''', 'mesh_file ''missing.obj'' not found', &
       cwd(max(1, len(cwd) - 20):)//'/missing.obj'])
    call bad('bad_shape.nml', [character(len=100) :: run, ball, &
      '&body name = ''rock'', shape = ''sphear'', radius = 1, density = 1 /'], &
      [character(len=60) :: 'bad_shape.nml:3:', '&body #2 ''rock''', 'unknown shape ''sphear''', &
       'did you mean ''sphere''?'])
    call bad('bad_no_shape.nml', [character(len=100) :: run, '&body radius = 1, density = 1 /'], &
      [character(len=60) :: 'bad_no_shape.nml:2:', '&body #1 ''body1''', 'shape is required'])
    call bad('bad_two_runs.nml', [character(len=100) :: run, ball, run], &
      [character(len=60) :: 'bad_two_runs.nml:3:', '&run appears again (first at line 1)'])
    call bad('bad_no_body.nml', [character(len=100) :: run, '&contact /'], &
      [character(len=60) :: 'bad_no_body.nml:', 'no &body group'])
    call bad('bad_no_run.nml', [character(len=100) :: ball], &
      [character(len=60) :: 'bad_no_run.nml:', 'no &run group'])
    call bad('bad_copies.nml', [character(len=100) :: run, ball, &
      '&body name = ''grid'', shape = ''sphere'', radius = 1, density = 1,', '  copies = 2, 0, 1, spacing = 3*3 /'], &
      [character(len=60) :: 'bad_copies.nml:4:', '&body #2 ''grid''', 'copies(2) must be >= 1'])
    call bad('bad_spacing.nml', [character(len=100) :: run, &
      '&body name = ''grid'', shape = ''sphere'', radius = 1, density = 1,', '  copies = 1, 1, 5 /'], &
      [character(len=60) :: 'bad_spacing.nml:3:', '&body #1 ''grid''', '5 copies along z need spacing(3) > 0'])
    call bad('bad_dt_max.nml', [character(len=100) :: '&run t_end = 1.0, dt_max = 2.0 /', ball], &
      [character(len=60) :: 'bad_dt_max.nml:1:', '&run:', 'dt_max = 2.0 s must not exceed t_end = 1.0 s'])
    call bad('bad_beta.nml', [character(len=100) :: run, '&integrator newmark_beta = 0.7 /', ball], &
      [character(len=60) :: 'bad_beta.nml:2:', '&integrator:', 'newmark_beta must be in [0, 0.5]', '2 beta >= gamma'])
    call bad('bad_gamma.nml', [character(len=100) :: run, '&integrator newmark_gamma = 0.4 /', ball], &
      [character(len=60) :: 'bad_gamma.nml:2:', '&integrator:', 'newmark_gamma must be in [0.5, 1]', 'unstable'])
    call bad('bad_rotation.nml', [character(len=100) :: run, ball, '&integrator rotation = ''euler'' /'], &
      [character(len=60) :: 'bad_rotation.nml:3:', '&integrator:', 'unknown rotation ''euler'''])
    call bad('bad_events.nml', [character(len=100) :: run, ball, '&integrator rotation = ''exact'',', &
      '  events = ''Fast'' /'], &
      [character(len=60) :: 'bad_events.nml:4:', '&integrator:', 'unknown events ''Fast''', &
       '(known: ''auto'', ''local'', ''global'')'])
    call bad('bad_events_type.nml', [character(len=100) :: run, ball, '&integrator events = local /'], &
      [character(len=60) :: 'bad_events_type.nml:3:', '&integrator:', 'events needs quoted text'])
    call bad('bad_iterations.nml', [character(len=100) :: run, ball, '&integrator rotation_max_iterations = 0 /'], &
      [character(len=60) :: 'bad_iterations.nml:3:', '&integrator:', 'rotation_max_iterations must be >= 1'])
    call bad('bad_integer.nml', [character(len=100) :: run, &
      '&body name = ''pin'', shape = ''cylinder'', radius = 1, size(3) = 2, segments = 3.5, density = 1 /'], &
      [character(len=60) :: 'bad_integer.nml:2:', '&body #1 ''pin''', 'segments needs a whole number, got ''3.5'''])
    call bad('bad_segments.nml', [character(len=100) :: run, &
      '&body name = ''pin'', shape = ''cylinder'', radius = 1, size(3) = 2, segments = 2, density = 1 /'], &
      [character(len=60) :: 'bad_segments.nml:2:', '&body #1 ''pin''', 'segments must be >= 3'])
    call bad('bad_cylinder_size.nml', [character(len=100) :: run, &
      '&body name = ''pin'', shape = ''cylinder'', radius = 1, size = 1, 1, 2, density = 1 /'], &
      [character(len=60) :: 'bad_cylinder_size.nml:2:', '&body #1 ''pin''', 'size(1) and size(2)'])
    call bad('bad_logical.nml', [character(len=100) :: run, ball, &
      '&body name = ''wall'', shape = ''box'', size = 1, 1, 1, fixed = ''yes'' /'], &
      [character(len=60) :: 'bad_logical.nml:3:', '&body #2 ''wall''', 'fixed needs .true. or .false.'])
    call bad('bad_count.nml', [character(len=100) :: run, ball, &
      '&body name = ''rock'', shape = ''sphere'', radius = 1, density = 1,', 'position = 1, 2 /'], &
      [character(len=60) :: 'bad_count.nml:4:', '&body #2 ''rock''', 'position takes 3 values, got 2'])
    call bad('bad_subscript.nml', [character(len=100) :: run, ball, &
      '&body name = ''rock'', shape = ''sphere'', radius = 1, density = 1, position(4) = 1 /'], &
      [character(len=60) :: 'bad_subscript.nml:3:', '&body #2 ''rock''', 'subscript out of range in ''position(4)'''])
    call bad('bad_scalar_subscript.nml', [character(len=100) :: '&run t_end(1) = 1.0, dt_max = 0.01 /', ball], &
      [character(len=60) :: 'bad_scalar_subscript.nml:1:', '&run:', 't_end is a single value'])
    call bad('bad_twice.nml', [character(len=100) :: run, ball, &
      '&body name = ''rock'', shape = ''sphere'', radius = 1, density = 1,', ' size = 1, 2, 3,', ' radius = 2 /'], &
      [character(len=60) :: 'bad_twice.nml:5:', '&body #2 ''rock''', 'radius is given twice (also on line 3)'])
    call bad('bad_not_applicable.nml', [character(len=100) :: run, &
      '&body name = ''crate'', shape = ''box'', size = 1, 1, 1, density = 1,', ' radius = 2 /'], &
      [character(len=60) :: 'bad_not_applicable.nml:3:', '&body #1 ''crate''', &
       'radius does not apply to shape ''box'''])
    call bad('bad_box_size.nml', [character(len=100) :: run, &
      '&body name = ''crate'', shape = ''box'', size(1:2) = 1, 1, density = 1 /'], &
      [character(len=60) :: 'bad_box_size.nml:2:', '&body #1 ''crate''', 'size(3) is missing'])
    call bad('bad_unclosed.nml', [character(len=100) :: run, ball, '&body name = ''rock'',', &
      '  shape = ''sphere'''], &
      [character(len=60) :: 'bad_unclosed.nml:3:', '&body #2 is not closed with ''/'''])
    call bad('bad_unclosed_next.nml', [character(len=100) :: '&run t_end = 1, dt_max = 0.1', ball], &
      [character(len=60) :: 'bad_unclosed_next.nml:2:', '&body starts before &run (line 1) is closed'])
    call bad('bad_outside.nml', [character(len=100) :: run, 'some words', ball], &
      [character(len=60) :: 'bad_outside.nml:2:', 'text outside a namelist group: ''some'''])
    call bad('bad_slash.nml', [character(len=100) :: run, ball, '&output dir = out/a /'], &
      [character(len=60) :: 'bad_slash.nml:3:', 'text after the ''/'' that closes &output', 'quote values'])
    call bad('bad_quote.nml', [character(len=100) :: '&run title = ''open, t_end = 1, dt_max = 0.1 /', ball], &
      [character(len=60) :: 'bad_quote.nml:1:', '&run', 'quoted value is not closed'])
    call bad('bad_empty_value.nml', [character(len=100) :: '&run t_end = 1, dt_max = 0.1,', ' gravity = 0,, -9.81 /', &
      ball], [character(len=60) :: 'bad_empty_value.nml:2:', '&run:', 'empty value in the list of ''gravity'''])
    call bad('bad_unquoted.nml', [character(len=100) :: run, '&body shape = sphere, radius = 1, density = 1 /'], &
      [character(len=60) :: 'bad_unquoted.nml:2:', '&body #1 ''body1''', 'shape needs quoted text'])
    call bad('bad_jitter_seed.nml', [character(len=100) :: run, &
      '&body name = ''j'', shape = ''sphere'', radius = 1, density = 1, jitter_position = 0.1 /'], &
      [character(len=60) :: 'bad_jitter_seed.nml:2:', '&body #1 ''j''', 'jitter needs a stated seed'])
    call bad('bad_jitter.nml', [character(len=100) :: run, &
      '&body name = ''j'', shape = ''sphere'', radius = 1, density = 1, seed = 3,', ' jitter_velocity = -1 /'], &
      [character(len=60) :: 'bad_jitter.nml:3:', '&body #1 ''j''', 'jitter_velocity must be >= 0'])
    call bad('bad_fixed_velocity.nml', [character(len=100) :: run, &
      '&body name = ''floor'', shape = ''box'', size = 1, 1, 1, fixed = t,', ' velocity(3) = 1 /'], &
      [character(len=60) :: 'bad_fixed_velocity.nml:3:', '&body #1 ''floor''', 'a fixed body never moves'])
    call bad('bad_same_name.nml', [character(len=100) :: run, ball, '! another', ball], &
      [character(len=60) :: 'bad_same_name.nml:4:', '&body #2 ''ball''', 'already used by &body #1 (line 2)'])
    call bad('bad_min_separation.nml', [character(len=100) :: run, ball, '&contact min_separation = -2 /'], &
      [character(len=60) :: 'bad_min_separation.nml:3:', '&contact:', 'min_separation must be > 0 m, or -1 for auto'])
    call bad('bad_interval.nml', [character(len=100) :: run, ball, '&output interval = 0 /'], &
      [character(len=60) :: 'bad_interval.nml:3:', '&output:', 'interval must be > 0 s'])
    call bad('bad_unknown_in_run.nml', [character(len=100) :: '&run t_end = 1, dt_max = 0.1, restitution = 1 /', ball], &
      [character(len=60) :: 'bad_unknown_in_run.nml:1:', '&run:', 'unknown variable ''restitution''', &
       'known: title, t_end'])
    call bad('bad_no_equals.nml', [character(len=100) :: '&run t_end 1, dt_max = 0.1 /', ball], &
      [character(len=60) :: 'bad_no_equals.nml:1:', '&run:', '''t_end'' without ''='''])
    call bad('bad_long_name.nml', [character(len=140) :: run, &
      '&body shape = ''sphere'', radius = 1, density = 1, name = '''//repeat('x', 70)//''' /'], &
      [character(len=60) :: 'bad_long_name.nml:2:', '&body #1', 'name is longer than 64 characters'])

    call bad('bad_scale.nml', [character(len=100) :: run, &
      '&body name = ''m'', shape = ''mesh'', mesh_file = ''sub/meshes/cube.obj'', scale = 0, density = 1 /'], &
      [character(len=60) :: 'bad_scale.nml:2:', '&body #1 ''m''', 'scale must be > 0'])
    call bad('bad_no_mesh_file.nml', [character(len=100) :: run, '&body name = ''m'', shape = ''mesh'', density = 1 /'], &
      [character(len=60) :: 'bad_no_mesh_file.nml:2:', '&body #1 ''m''', 'a mesh needs mesh_file'])
    call bad('bad_segments_sphere.nml', [character(len=100) :: run, ball, &
      '&body name = ''s'', shape = ''sphere'', radius = 1, density = 1,', ' segments = 8 /'], &
      [character(len=60) :: 'bad_segments_sphere.nml:4:', '&body #2 ''s''', 'segments does not apply to shape ''sphere'''])
    call bad('bad_density.nml', [character(len=100) :: run, '&body shape = ''sphere'', radius = 1,', ' density = 0 /'], &
      [character(len=60) :: 'bad_density.nml:3:', '&body #1 ''body1''', 'density must be > 0 kg/m^3'])
    call bad('bad_jitter_angle.nml', [character(len=100) :: run, &
      '&body name = ''j'', shape = ''sphere'', radius = 1, density = 1, seed = 1, jitter_angle = 4 /'], &
      [character(len=60) :: 'bad_jitter_angle.nml:2:', '&body #1 ''j''', 'jitter_angle must be in [0, pi]'])
    call bad('bad_seed.nml', [character(len=100) :: run, &
      '&body name = ''j'', shape = ''sphere'', radius = 1, density = 1, seed = -3 /'], &
      [character(len=60) :: 'bad_seed.nml:2:', '&body #1 ''j''', 'seed must be >= 0'])
    call bad('bad_spacing_negative.nml', [character(len=100) :: run, &
      '&body name = ''g'', shape = ''sphere'', radius = 1, density = 1, spacing = 1, -1, 1 /'], &
      [character(len=60) :: 'bad_spacing_negative.nml:2:', '&body #1 ''g''', 'spacing(2) must be >= 0 m'])
    call bad('bad_checkpoint.nml', [character(len=100) :: run, ball, '&output checkpoint_interval = -1 /'], &
      [character(len=60) :: 'bad_checkpoint.nml:3:', '&output:', 'checkpoint_interval must be >= 0'])
    call bad('bad_progress.nml', [character(len=100) :: run, ball, '&output', ' progress_interval = 0 /'], &
      [character(len=60) :: 'bad_progress.nml:4:', '&output:', 'progress_interval must be > 0'])
    call bad('bad_blank_dir.nml', [character(len=100) :: run, ball, '&output dir = '' '' /'], &
      [character(len=60) :: 'bad_blank_dir.nml:3:', '&output:', 'dir must not be blank'])
    call bad('bad_tolerance.nml', [character(len=100) :: run, ball, '&integrator rotation_tolerance = 0 /'], &
      [character(len=60) :: 'bad_tolerance.nml:3:', '&integrator:', 'rotation_tolerance must be in (0, 1)'])
    call bad('bad_integer_range.nml', [character(len=100) :: run, ball, '&integrator', &
      '  rotation_max_iterations = 99999999999 /'], &
      [character(len=60) :: 'bad_integer_range.nml:4:', '&integrator:', 'out of range for an integer'])
    call bad('bad_repeat.nml', [character(len=100) :: run, &
      '&body shape = ''sphere'', radius = 1, density = 1, position = 0*1 /'], &
      [character(len=60) :: 'bad_repeat.nml:2:', '&body #1 ''body1''', 'bad repeat count in ''0*1'''])
    call bad('bad_null_repeat.nml', [character(len=100) :: run, &
      '&body shape = ''sphere'', radius = 1, density = 1, position = 3* /'], &
      [character(len=60) :: 'bad_null_repeat.nml:2:', '&body #1 ''body1''', '''3*'' without a value'])
    call bad('bad_component.nml', [character(len=100) :: '&run t_end = 1, dt_max = 0.1, run%title = ''x'' /', ball], &
      [character(len=60) :: 'bad_component.nml:1:', '&run:', 'derived-type components'])
    call bad('bad_misplaced_equals.nml', [character(len=100) :: '&run t_end = 1, dt_max = 0.1, gravity = 0, 0, = 1 /', &
      ball], [character(len=60) :: 'bad_misplaced_equals.nml:1:', '&run:', 'misplaced ''='' in the values of ''gravity'''])
    call bad('bad_no_value.nml', [character(len=100) :: '&run dt_max = 0.1, t_end = /', ball], &
      [character(len=60) :: 'bad_no_value.nml:1:', '&run:', '''t_end ='' has no value'])
    call bad('bad_amp.nml', [character(len=100) :: run, '& shape = 1 /', ball], &
      [character(len=60) :: 'bad_amp.nml:2:', '''&'' without a group name'])

    ! The tetrahedron, torus and L prism: their variables, and theirs refused elsewhere.
    call bad('bad_tet_size2.nml', [character(len=100) :: run, &
      '&body name = ''t'', shape = ''tetrahedron'', size(1) = 1, density = 1,', ' size(2) = 1 /'], &
      [character(len=60) :: 'bad_tet_size2.nml:3:', '&body #1 ''t''', 'size(2) and size(3) do not apply'])
    call bad('bad_tet_size3.nml', [character(len=100) :: run, &
      '&body name = ''t'', shape = ''tetrahedron'', density = 1,', ' size = 1, 1, 1 /'], &
      [character(len=60) :: 'bad_tet_size3.nml:3:', '&body #1 ''t''', 'takes its edge length as size(1)'])
    call bad('bad_tet_no_size.nml', [character(len=100) :: run, ball, &
      '&body name = ''t'', shape = ''tetrahedron'', density = 1 /'], &
      [character(len=60) :: 'bad_tet_no_size.nml:3:', '&body #2 ''t''', 'a tetrahedron needs its edge length'])
    call bad('bad_tet_edge.nml', [character(len=100) :: run, &
      '&body name = ''t'', shape = ''tetrahedron'', density = 1,', ' size(1) = -0.5 /'], &
      [character(len=60) :: 'bad_tet_edge.nml:3:', '&body #1 ''t''', 'edge length) must be > 0 m, got -0.5'])
    call bad('bad_tet_radius.nml', [character(len=100) :: run, &
      '&body name = ''t'', shape = ''tetrahedron'', size(1) = 1, density = 1,', ' radius = 1 /'], &
      [character(len=60) :: 'bad_tet_radius.nml:3:', '&body #1 ''t''', 'radius does not apply to shape ''tetrahedron''', &
       'takes size(1)'])
    call bad('bad_torus_no_radius.nml', [character(len=100) :: run, &
      '&body name = ''o'', shape = ''torus'', minor_radius = 0.1, density = 1 /'], &
      [character(len=60) :: 'bad_torus_no_radius.nml:2:', '&body #1 ''o''', 'a torus needs radius [m]'])
    call bad('bad_torus_no_minor.nml', [character(len=100) :: run, &
      '&body name = ''o'', shape = ''torus'', radius = 1, density = 1 /'], &
      [character(len=60) :: 'bad_torus_no_minor.nml:2:', '&body #1 ''o''', 'a torus needs minor_radius [m]'])
    call bad('bad_torus_minor.nml', [character(len=100) :: run, &
      '&body name = ''o'', shape = ''torus'', radius = 1, density = 1,', ' minor_radius = 0 /'], &
      [character(len=60) :: 'bad_torus_minor.nml:3:', '&body #1 ''o''', 'minor_radius must be > 0 m, got 0.0'])
    call bad('bad_torus_no_hole.nml', [character(len=100) :: run, &
      '&body name = ''o'', shape = ''torus'', radius = 1, density = 1,', ' minor_radius = 1 /'], &
      [character(len=60) :: 'bad_torus_no_hole.nml:3:', '&body #1 ''o''', &
       'minor_radius = 1.0 m must be < radius = 1.0 m'])
    call bad('bad_torus_segments.nml', [character(len=100) :: run, &
      '&body name = ''o'', shape = ''torus'', radius = 1, minor_radius = 0.5, density = 1,', ' segments = 2 /'], &
      [character(len=60) :: 'bad_torus_segments.nml:3:', '&body #1 ''o''', 'segments must be >= 3, got 2'])
    call bad('bad_tube_segments.nml', [character(len=100) :: run, &
      '&body name = ''o'', shape = ''torus'', radius = 1, minor_radius = 0.5, density = 1,', ' tube_segments = 2 /'], &
      [character(len=60) :: 'bad_tube_segments.nml:3:', '&body #1 ''o''', 'tube_segments must be >= 3, got 2'])
    call bad('bad_tube_segments_type.nml', [character(len=100) :: run, &
      '&body name = ''o'', shape = ''torus'', radius = 1, minor_radius = 0.5, density = 1,', ' tube_segments = 8.5 /'], &
      [character(len=60) :: 'bad_tube_segments_type.nml:3:', '&body #1 ''o''', 'tube_segments needs a whole number'])
    call bad('bad_torus_faces.nml', [character(len=100) :: run, &
      '&body name = ''o'', shape = ''torus'', radius = 1, minor_radius = 0.5, density = 1,', &
      ' segments = 100000, tube_segments = 100000 /'], &
      [character(len=60) :: 'bad_torus_faces.nml:3:', '&body #1 ''o''', 'makes more than 2147483647 faces'])
    call bad('bad_torus_size.nml', [character(len=100) :: run, &
      '&body name = ''o'', shape = ''torus'', radius = 1, minor_radius = 0.5, density = 1,', ' size(3) = 1 /'], &
      [character(len=60) :: 'bad_torus_size.nml:3:', '&body #1 ''o''', 'size does not apply to shape ''torus''', &
       'a torus takes radius, minor_radius'])
    call bad('bad_minor_radius_sphere.nml', [character(len=100) :: run, &
      '&body name = ''s'', shape = ''sphere'', radius = 1, density = 1,', ' minor_radius = 0.5 /'], &
      [character(len=60) :: 'bad_minor_radius_sphere.nml:3:', '&body #1 ''s''', &
       'minor_radius does not apply to shape ''sphere'''])
    call bad('bad_tube_segments_cylinder.nml', [character(len=100) :: run, &
      '&body name = ''c'', shape = ''cylinder'', radius = 1, size(3) = 1, density = 1,', ' tube_segments = 8 /'], &
      [character(len=60) :: 'bad_tube_segments_cylinder.nml:3:', '&body #1 ''c''', &
       'tube_segments does not apply to shape ''cylinder'''])
    call bad('bad_thickness_box.nml', [character(len=100) :: run, &
      '&body name = ''b'', shape = ''box'', size = 1, 1, 1, density = 1,', ' thickness = 0.1 /'], &
      [character(len=60) :: 'bad_thickness_box.nml:3:', '&body #1 ''b''', 'thickness does not apply to shape ''box'''])
    call bad('bad_thickness_mesh.nml', [character(len=100) :: run, &
      '&body name = ''m'', shape = ''mesh'', mesh_file = ''sub/meshes/cube.obj'', density = 1,', ' thickness = 0.1 /'], &
      [character(len=60) :: 'bad_thickness_mesh.nml:3:', '&body #1 ''m''', 'thickness does not apply to shape ''mesh'''])
    call bad('bad_l_no_thickness.nml', [character(len=100) :: run, &
      '&body name = ''l'', shape = ''l_prism'', size = 1, 1, 1, density = 1 /'], &
      [character(len=60) :: 'bad_l_no_thickness.nml:2:', '&body #1 ''l''', 'an l_prism needs thickness [m]'])
    call bad('bad_l_thickness.nml', [character(len=100) :: run, &
      '&body name = ''l'', shape = ''l_prism'', size = 1, 1, 1, density = 1,', ' thickness = -0.1 /'], &
      [character(len=60) :: 'bad_l_thickness.nml:3:', '&body #1 ''l''', 'thickness must be > 0 m, got -0.1'])
    call bad('bad_l_thick.nml', [character(len=100) :: run, &
      '&body name = ''l'', shape = ''l_prism'', size = 2, 0.5, 1, density = 1,', ' thickness = 0.5 /'], &
      [character(len=60) :: 'bad_l_thick.nml:3:', '&body #1 ''l''', &
       'thickness = 0.5 m must be < min(size(1), size(2)) = 0.5 m'])
    call bad('bad_l_size.nml', [character(len=100) :: run, &
      '&body name = ''l'', shape = ''l_prism'', thickness = 0.1, density = 1,', ' size(1:2) = 1, 1 /'], &
      [character(len=60) :: 'bad_l_size.nml:3:', '&body #1 ''l''', 'an l_prism needs all three lengths', &
       'size(3) is missing'])
    call bad('bad_l_size_negative.nml', [character(len=100) :: run, &
      '&body name = ''l'', shape = ''l_prism'', thickness = 0.1, density = 1,', ' size = 1, -1, 1 /'], &
      [character(len=60) :: 'bad_l_size_negative.nml:3:', '&body #1 ''l''', 'size(2) must be > 0 m'])
    call bad('bad_l_segments.nml', [character(len=100) :: run, &
      '&body name = ''l'', shape = ''l_prism'', size = 1, 1, 1, thickness = 0.1, density = 1,', ' segments = 8 /'], &
      [character(len=60) :: 'bad_l_segments.nml:3:', '&body #1 ''l''', 'segments does not apply to shape ''l_prism''', &
       'an l_prism takes size = x, y, z and thickness'])
    call bad('bad_shape_torus.nml', [character(len=100) :: run, &
      '&body name = ''o'', shape = ''tours'', radius = 1, density = 1 /'], &
      [character(len=60) :: 'bad_shape_torus.nml:2:', '&body #1 ''o''', 'unknown shape ''tours''', &
       'did you mean ''torus''?', 'tetrahedron, torus, l_prism, mesh'])
    call bad('bad_shape_l.nml', [character(len=100) :: run, &
      '&body name = ''l'', shape = ''l-prism'', density = 1 /'], &
      [character(len=60) :: 'bad_shape_l.nml:2:', '&body #1 ''l''', 'did you mean ''l_prism''?'])

    ! Materials: -1 (the &contact value) or a valid value; rest_speed: -1 (auto) or >= 0.
    call bad('bad_body_restitution.nml', [character(len=100) :: run, ball, &
      '&body name = ''r'', shape = ''sphere'', radius = 1, density = 1,', ' restitution = 1.5 /'], &
      [character(len=60) :: 'bad_body_restitution.nml:4:', '&body #2 ''r''', 'restitution must be in [0, 1]', &
       'or -1 for the &contact value, got 1.5'])
    call bad('bad_body_restitution_negative.nml', [character(len=100) :: run, &
      '&body name = ''floor'', shape = ''box'', size = 1, 1, 1, fixed = t,', ' restitution = -0.5 /'], &
      [character(len=60) :: 'bad_body_restitution_negative.nml:3:', '&body #1 ''floor''', &
       'restitution must be in [0, 1]', 'got -0.5'])
    call bad('bad_body_friction.nml', [character(len=100) :: run, &
      '&body name = ''r'', shape = ''sphere'', radius = 1, density = 1,', ' friction = -2 /'], &
      [character(len=60) :: 'bad_body_friction.nml:3:', '&body #1 ''r''', 'friction must be >= 0', &
       'or -1 for the &contact value, got -2.0'])
    call bad('bad_body_friction_nan.nml', [character(len=100) :: run, &
      '&body name = ''r'', shape = ''sphere'', radius = 1, density = 1,', ' friction = nan /'], &
      [character(len=60) :: 'bad_body_friction_nan.nml:3:', '&body #1 ''r''', 'friction must be a finite number'])
    call bad('bad_body_friction_twice.nml', [character(len=100) :: run, &
      '&body name = ''r'', shape = ''sphere'', radius = 1, density = 1, friction = 0.1,', ' friction = 0.2 /'], &
      [character(len=60) :: 'bad_body_friction_twice.nml:3:', '&body #1 ''r''', 'friction is given twice'])
    call bad('bad_rest_speed.nml', [character(len=100) :: run, ball, '&contact', ' rest_speed = -0.5 /'], &
      [character(len=60) :: 'bad_rest_speed.nml:4:', '&contact:', 'rest_speed must be >= 0 m/s, or -1 for auto', &
       'got -0.5'])
    call bad('bad_rest_speed_type.nml', [character(len=100) :: run, ball, '&contact rest_speed = ''fast'' /'], &
      [character(len=60) :: 'bad_rest_speed_type.nml:3:', '&contact:', 'rest_speed needs a number'])
    call bad('bad_rest_speed_body.nml', [character(len=100) :: run, &
      '&body name = ''r'', shape = ''sphere'', radius = 1, density = 1,', ' rest_speed = 0.1 /'], &
      [character(len=60) :: 'bad_rest_speed_body.nml:3:', '&body #1 ''r''', 'unknown variable ''rest_speed'''])

    ! A deck that does not exist: an I/O error naming it.
    call err%clear()
    call read_deck('no_such_deck.nml', deck, err)
    f(1) = 'no_such_deck.nml'
    f(2) = 'cannot open the deck'
    call check_error(err%code, message(err), f(1:2), 'missing deck')
    call check(err%code == ERR_IO, 'missing deck is an I/O error')
  end subroutine test_bad_decks

  function message(err) result(text)
    type(error_t), intent(in) :: err
    character(len=:), allocatable :: text
    text = ''
    if (allocated(err%message)) text = err%message
  end function message

  function str_i(i) result(text)
    integer, intent(in) :: i
    character(len=:), allocatable :: text
    character(len=16) :: buffer
    write (buffer, '(i0)') i
    text = trim(buffer)
  end function str_i

end program test_deck_reader
