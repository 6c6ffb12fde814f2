!> The second-order bound for turning bodies near contact (src/contact/plane_bound.f90):
!>  - safe: for random tumbling poses just above the contact band (cube on a floor, cube on
!>    a cube, ball on a cube, both bodies moving and turning, under gravity), the true mesh
!>    distance along the exact flight never falls below the floor before the safe time;
!>  - useful: a cube rocking on its edge just above a floor gets a safe time within a
!>    factor 2 of the true crossing, where the first-order bound (Omega R) gives 1/15 of it;
!>  - a pair already below the floor that recedes is safe while it cannot come closer;
!>  - it refuses (returns 0) what it cannot bound: a vertex below the floor that does not
!>    recede, and turning meshes under the Newmark propagator.
program test_plane_bound
  use kinds, only: dp
  use error_status, only: error_t
  use mesh, only: mesh_t
  use shape, only: shape_t, shape_library_t
  use shape_factory, only: make_mesh_shape, make_sphere_shape
  use shape_builders, only: box_mesh
  use body_state, only: bodies_t
  use free_flight, only: free_flight_t
  use input_config, only: integrator_config_t, ROTATION_EXACT
  use pair_geometry, only: pair_gap
  use plane_bound, only: plane_safe_time
  use quaternion, only: quat_rotate, quat_exp
  use mesh_fixtures, only: random_unit_quaternion, random_unit_vector, axis_angle_quaternion
  use assertions
  implicit none

  integer, parameter :: FLOOR = 1, CUBE_A = 2, CUBE_B = 3, BALL = 4
  real(dp), parameter :: gravity(3) = [0.0_dp, 0.0_dp, -9.81_dp]
  real(dp), parameter :: rho = 1000.0_dp, edge = 0.2_dp, ball_r = 0.1_dp
  real(dp), parameter :: h = 0.02_dp   ! the step every bound must hold over [s]
  integer, parameter :: trials = 60, samples = 400
  type(shape_library_t) :: shapes
  type(bodies_t) :: bodies
  type(free_flight_t) :: flight
  type(integrator_config_t) :: config
  integer :: trial, useful(3), k
  real(dp) :: t_safe, t_cross, first_order, gap0, floor_gap, normal(3), worst(3)
  character(len=32) :: names(3) = [character(len=32) :: 'cube on floor', 'cube on cube', 'ball on cube']

  call build_scene()
  config%rotation = ROTATION_EXACT
  call flight%init(bodies%n_owned, config)

  ! 1. Safety over random tumbling poses. worst(k): the smallest (true gap - floor) seen
  !    before the safe time; a safe bound keeps it >= 0 (1e-12 m: the distance query's
  !    round-off on 0.2 m bodies). useful(k): trials with a safe time > 0, so that the test
  !    exercises the bound and not only its refusals.
  worst = huge(1.0_dp)
  useful = 0
  do k = 1, 3
    do trial = 1, trials
      call random_pose(k, gap0)
      call pair_gap(shapes, bodies, pair_i(k), pair_j(k), bodies%x(:, pair_i(k)), bodies%q(:, pair_i(k)), &
                    bodies%x(:, pair_j(k)), bodies%q(:, pair_j(k)), gap0, normal)
      floor_gap = gap0*(0.2_dp + 0.6_dp*uniform())
      t_safe = plane_safe_time(shapes, bodies, flight, gravity, pair_i(k), pair_j(k), normal, floor_gap, h)
      if (t_safe > 0.0_dp) useful(k) = useful(k) + 1
      worst(k) = min(worst(k), smallest_gap(pair_i(k), pair_j(k), min(t_safe, h)) - floor_gap)
    end do
    write (*, '(a,a,es10.3,a,i0,a,i0)') trim(names(k)), ': smallest (gap - floor) before the safe time ', &
      worst(k), ' m; safe time > 0 in ', useful(k), ' of ', trials
    call check(worst(k) >= -1.0e-12_dp, trim(names(k))//': true gap never below the floor before the safe time')
    call check(useful(k) >= trials/2, trim(names(k))//': the bound gives a safe time in most trials')
  end do

  ! 2. Tightness: a cube rocking about its lowest edge (w = 2 rad/s along the edge), the
  !    edge 1e-4 m above the floor, floor 5e-5 m, falling under gravity. The true crossing
  !    comes from gravity (the edge rises as it turns): ~sqrt(2 * 5e-5 / 9.81) = 3.2 ms.
  !    The bound adds Omega^2 R to g (10.4 against 9.81 m/s^2): within a factor 2 of the
  !    crossing, where the first-order bound allows 5e-5 / (Omega R) = 0.18 ms.
  call rocking_cube()
  call pair_gap(shapes, bodies, FLOOR, CUBE_A, bodies%x(:, FLOOR), bodies%q(:, FLOOR), bodies%x(:, CUBE_A), &
                bodies%q(:, CUBE_A), gap0, normal)
  t_safe = plane_safe_time(shapes, bodies, flight, gravity, FLOOR, CUBE_A, [0.0_dp, 0.0_dp, 1.0_dp], 5.0e-5_dp, h)
  t_cross = crossing_time(FLOOR, CUBE_A, 5.0e-5_dp, h)
  first_order = 5.0e-5_dp/(norm2(bodies%w(:, CUBE_A))*shapes%shapes(bodies%shape_id(CUBE_A))%bounding_radius)
  write (*, '(a,3es11.3,a)') 'rocking cube: safe time, true crossing, first-order bound ', t_safe, t_cross, &
    first_order, ' s'
  call check_close(gap0, 1.0e-4_dp, 1.0e-9_dp, 'rocking cube: starts 1e-4 m above the floor')
  call check(t_safe <= t_cross, 'rocking cube: safe time before the true crossing')
  call check(t_safe >= 0.5_dp*t_cross, 'rocking cube: safe time within a factor 2 of the crossing')
  call check(t_safe >= 10.0_dp*first_order, 'rocking cube: 10x the first-order bound')

  ! 3. A pair below the floor that recedes (the distance correction could not open it):
  !    safe while it cannot come closer than now. The cube lifts off at 0.01 m/s while
  !    turning at 3 rad/s about its lowest edge, which is 1e-5 m up; the floor asked is 2e-5 m.
  call rocking_cube()
  bodies%x(3, CUBE_A) = bodies%x(3, CUBE_A) - 0.9e-4_dp
  bodies%v(:, CUBE_A) = [0.0_dp, 0.0_dp, 0.01_dp]
  bodies%w(:, CUBE_A) = [3.0_dp, 0.02_dp, 0.0_dp]   ! both ends of the lowest edge rise
  call flight%release_all()
  gap0 = smallest_gap(FLOOR, CUBE_A, 0.0_dp)
  t_safe = plane_safe_time(shapes, bodies, flight, gravity, FLOOR, CUBE_A, [0.0_dp, 0.0_dp, 1.0_dp], 2.0e-5_dp, h)
  write (*, '(a,2es11.3)') 'receding below the floor: gap now, safe time ', gap0, t_safe
  call check(t_safe > 0.0_dp, 'receding below the floor: a safe time')
  call check(smallest_gap(FLOOR, CUBE_A, min(t_safe, h)) >= gap0 - 1.0e-12_dp, &
             'receding below the floor: never closer than now before the safe time')

  ! 4. Refusals: below the floor already and not receding (the rocking cube's lowest edge
  !    moves sideways while the cube falls at 0.01 m/s), and Newmark rotation (no exact
  !    energy bound).
  call rocking_cube()
  bodies%v(:, CUBE_A) = [0.0_dp, 0.0_dp, -0.01_dp]
  call flight%release_all()
  t_safe = plane_safe_time(shapes, bodies, flight, gravity, FLOOR, CUBE_A, [0.0_dp, 0.0_dp, 1.0_dp], 2.0e-4_dp, h)
  call check(t_safe == 0.0_dp, 'a vertex below the floor already: no safe time')
  config%rotation = 'newmark'
  call flight%init(bodies%n_owned, config)
  t_safe = plane_safe_time(shapes, bodies, flight, gravity, FLOOR, CUBE_A, [0.0_dp, 0.0_dp, 1.0_dp], 5.0e-5_dp, h)
  call check(t_safe == 0.0_dp, 'Newmark rotation: no safe time for a turning mesh')

  call test_finish()

contains

  integer function pair_i(k)
    integer, intent(in) :: k
    integer, parameter :: first(3) = [FLOOR, CUBE_A, BALL]
    pair_i = first(k)
  end function pair_i

  integer function pair_j(k)
    integer, intent(in) :: k
    integer, parameter :: second(3) = [CUBE_A, CUBE_B, CUBE_A]
    pair_j = second(k)
  end function pair_j

  real(dp) function uniform()
    call random_number(uniform)
  end function uniform

  !> A static floor (top at z = 0), two 0.2 m cubes and a 0.1 m analytic ball.
  subroutine build_scene()
    type(mesh_t) :: m
    type(shape_t) :: s
    type(error_t) :: err
    integer :: id_floor, id_cube, id_ball
    call box_mesh([4.0_dp, 4.0_dp, 1.0_dp], m)
    call make_mesh_shape(m, 'floor', s, err)
    call check(.not. err%failed(), 'floor shape')
    call s%tree%build(s%mesh, err)
    call shapes%add(s, id_floor)
    call box_mesh([edge, edge, edge], m)
    call make_mesh_shape(m, 'cube', s, err)
    call check(.not. err%failed(), 'cube shape')
    call s%tree%build(s%mesh, err)
    call shapes%add(s, id_cube)
    call make_sphere_shape(ball_r, s)
    call shapes%add(s, id_ball)

    call bodies%allocate(4)
    bodies%n_owned = 4
    bodies%shape_id = [id_floor, id_cube, id_cube, id_ball]
    do k = 1, 4
      bodies%gid(k) = k
      associate (sh => shapes%shapes(bodies%shape_id(k)))
        bodies%mass(k) = rho*sh%volume
        bodies%inv_mass(k) = 1.0_dp/bodies%mass(k)
        bodies%inertia(:, k) = rho*sh%unit_inertia
        bodies%inv_inertia(:, k) = 1.0_dp/bodies%inertia(:, k)
      end associate
    end do
    bodies%fixed(FLOOR) = .true.
    bodies%inv_mass(FLOOR) = 0.0_dp
    bodies%inv_inertia(:, FLOOR) = 0.0_dp
    bodies%x(:, FLOOR) = [0.0_dp, 0.0_dp, -0.5_dp]
  end subroutine build_scene

  !> Places the pair of case k a random small gap apart (1e-5 .. 1e-3 m, measured along z
  !> by the lowest point of the upper body) with random orientations, velocities up to
  !> 0.05 m/s and angular velocities up to 4 rad/s. The other bodies are put far away.
  subroutine random_pose(k, gap_along_z)
    integer, intent(in) :: k
    real(dp), intent(out) :: gap_along_z
    real(dp) :: lift
    integer :: b
    do b = 2, 4
      bodies%x(:, b) = [10.0_dp*b, 0.0_dp, 5.0_dp]
      bodies%q(:, b) = random_unit_quaternion()
      bodies%v(:, b) = 0.05_dp*uniform()*random_unit_vector()
      bodies%w(:, b) = 4.0_dp*uniform()*random_unit_vector()
    end do
    lift = 1.0e-5_dp*100.0_dp**uniform()
    select case (k)
    case (1)   ! cube over the floor
      bodies%x(:, CUBE_A) = [0.0_dp, 0.0_dp, lowest_offset(CUBE_A) + lift]
    case (2)   ! cube B's lowest vertex over the middle of cube A's flat top face
      call flat_cube_a()
      bodies%x(:, CUBE_B) = 0.0_dp
      bodies%x(:, CUBE_B) = [0.03_dp*uniform(), 0.03_dp*uniform(), 1.0_dp + 0.5_dp*edge + lowest_offset(CUBE_B) + lift] &
                            - [lowest_vertex(CUBE_B), 0.0_dp]
    case (3)   ! the ball over cube A's flat top face
      call flat_cube_a()
      bodies%x(:, BALL) = [0.05_dp*uniform(), 0.05_dp*uniform(), 1.0_dp + 0.5_dp*edge + ball_r + lift]
    end select
    ! the cube below turns more slowly in cases 2 and 3
    if (k > 1) bodies%w(:, CUBE_A) = 0.5_dp*uniform()*random_unit_vector()
    gap_along_z = lift
    call flight%release_all()
  end subroutine random_pose

  !> Cube A at (0, 0, 1) m with its faces along the world axes (q = the shape's principal
  !> frame in its box frame), so that its top face is flat at z = 1 + edge/2.
  subroutine flat_cube_a()
    bodies%q(:, CUBE_A) = shapes%shapes(bodies%shape_id(CUBE_A))%q_principal
    bodies%x(:, CUBE_A) = [0.0_dp, 0.0_dp, 1.0_dp]
  end subroutine flat_cube_a

  !> Horizontal position (x, y) of body b's lowest vertex relative to its centre [m].
  function lowest_vertex(b) result(xy)
    integer, intent(in) :: b
    real(dp) :: xy(2), p(3), z_min
    integer :: v
    z_min = huge(1.0_dp)
    associate (nodes => shapes%shapes(bodies%shape_id(b))%mesh%nodes)
      do v = 1, size(nodes, 2)
        p = quat_rotate(bodies%q(:, b), nodes(:, v))
        if (p(3) < z_min) then
          z_min = p(3)
          xy = p(1:2)
        end if
      end do
    end associate
  end function lowest_vertex

  !> Depth of body b's lowest vertex below its centre of mass at its current orientation [m].
  real(dp) function lowest_offset(b)
    integer, intent(in) :: b
    lowest_offset = reach(b, [0.0_dp, 0.0_dp, -1.0_dp])
  end function lowest_offset

  !> Support of body b along the unit direction dir, from its centre of mass [m].
  real(dp) function reach(b, dir)
    integer, intent(in) :: b
    real(dp), intent(in) :: dir(3)
    integer :: v
    reach = -huge(1.0_dp)
    associate (nodes => shapes%shapes(bodies%shape_id(b))%mesh%nodes)
      do v = 1, size(nodes, 2)
        reach = max(reach, dot_product(quat_rotate(bodies%q(:, b), nodes(:, v)), dir))
      end do
    end associate
  end function reach

  !> Cube A standing on an edge (45 degrees about x), the edge 1e-4 m above the floor,
  !> at rest except w = 2 rad/s about the edge's direction.
  subroutine rocking_cube()
    call random_pose(1, gap0)
    bodies%q(:, CUBE_A) = axis_angle_quaternion([1.0_dp, 0.0_dp, 0.0_dp], atan(1.0_dp))
    bodies%x(:, CUBE_A) = [0.0_dp, 0.0_dp, 0.0_dp]
    bodies%x(3, CUBE_A) = lowest_offset(CUBE_A) + 1.0e-4_dp
    bodies%v(:, CUBE_A) = 0.0_dp
    bodies%w(:, CUBE_A) = [2.0_dp, 0.0_dp, 0.0_dp]
    call flight%release_all()
  end subroutine rocking_cube

  !> Smallest true gap of the pair over [0, t_end] on `samples` evenly spaced poses of the
  !> exact flight (t_end = 0: the gap now).
  real(dp) function smallest_gap(i, j, t_end) result(g_min)
    integer, intent(in) :: i, j
    real(dp), intent(in) :: t_end
    real(dp) :: xi(3), qi(4), xj(3), qj(4), g, n(3), t
    integer :: s
    g_min = huge(1.0_dp)
    do s = 0, samples
      t = t_end*real(s, dp)/samples
      call flight%pose_at(bodies, i, 0.0_dp, t, gravity, config, xi, qi)
      call flight%pose_at(bodies, j, 0.0_dp, t, gravity, config, xj, qj)
      call pair_gap(shapes, bodies, i, j, xi, qi, xj, qj, g, n)
      g_min = min(g_min, g)
      if (t_end == 0.0_dp) exit
    end do
  end function smallest_gap

  !> First sampled time in [0, t_end] at which the true gap is at or below level [s]
  !> (t_end if never): resolution t_end/(20 samples).
  real(dp) function crossing_time(i, j, level, t_end) result(t)
    integer, intent(in) :: i, j
    real(dp), intent(in) :: level, t_end
    real(dp) :: xi(3), qi(4), xj(3), qj(4), g, n(3)
    integer :: s
    do s = 0, 20*samples
      t = t_end*real(s, dp)/(20*samples)
      call flight%pose_at(bodies, i, 0.0_dp, t, gravity, config, xi, qi)
      call flight%pose_at(bodies, j, 0.0_dp, t, gravity, config, xj, qj)
      call pair_gap(shapes, bodies, i, j, xi, qi, xj, qj, g, n)
      if (g <= level) return
    end do
  end function crossing_time

end program test_plane_bound
