!> Time of contact of the step's candidate pairs by conservative advancement (time_of_contact)
!> with the motion the propagator will make: the earliest over all pairs and the pairs that
!> reach contact then (earliest_contact), one pair's (advance_candidate, also what the local
!> event loop computes for a pair whose certificate is due), the re-tests of receding pairs
!> along the step (extend_receding), and the closest points at a time in the step
!> (pair_oracle_t). A submodule: it reads the stage's pair table and its tolerances.
submodule (collision_stage) collision_stage_advance
  use time_of_contact, only: pair_motion_t, distance_oracle_t, advance_pair
  use impulse_solver, only: normal_velocity
  use pair_geometry, only: pair_gap, pair_contact_points, convex_pair, convex_pair_bound
  use plane_bound, only: plane_safe_time, plane_time, plane_body_at, plane_body_t
  use gap_memo, only: gap_memo_t
  use turning_bound, only: turning_body_t, turning_body, directional_time
  implicit none

  !> Closest points of one pair at time_now + t, with the poses the propagator will give.
  type, extends(distance_oracle_t) :: pair_oracle_t
    type(free_flight_t), pointer :: flight => null()
    type(bodies_t), pointer :: bodies => null()
    type(shape_library_t), pointer :: shapes => null()
    type(gap_memo_t), pointer :: memo => null()
    type(integrator_config_t) :: config
    integer :: i = 0, j = 0
    real(dp) :: time_now = 0.0_dp, gravity(3) = 0.0_dp
    real(dp) :: min_gap = huge(1.0_dp)
    !> the directional bound applies (exact propagator, both bodies convex)
    logical :: directional = .false.
    !> both bodies convex meshes with few vertices: the iterates above the band take GJK's
    !> certified lower bound (convex_distance) instead of the exact query
    logical :: gjk = .false.
    integer(i8) :: bounds = 0      !< iterates answered by the GJK bound
    !> the poses of the last gap_at (the bound starts where the query was made)
    real(dp) :: t_pose = -huge(1.0_dp)
    real(dp) :: x_pose(3, 2) = 0.0_dp, q_pose(4, 2) = 0.0_dp, w_pose(3, 2) = 0.0_dp
  contains
    procedure :: gap_at => oracle_gap_at
    procedure :: gap_at_time => oracle_gap_at_time
    procedure :: lower_gap_at => oracle_lower_gap_at
    procedure :: turning_time => oracle_turning_time
  end type pair_oracle_t


  !> The vertex of an analytic sphere: its centre (the radius is swept around it).
  real(dp), parameter :: sphere_node(3, 1) = 0.0_dp

contains

  !> Earliest time of contact in [0, h] over all candidate pairs: h_event <= h. The pairs
  !> that reach contact at h_event are kept for resolve.
  module subroutine stage_earliest_contact(self, bodies, shapes, flight, time_now, h, gravity, config, h_event, err)
    class(collision_stage_t), intent(inout) :: self
    type(bodies_t), intent(inout), target :: bodies
    type(shape_library_t), intent(in), target :: shapes
    type(free_flight_t), intent(inout), target :: flight
    real(dp), intent(in) :: time_now, h, gravity(3)
    type(integrator_config_t), intent(in) :: config
    real(dp), intent(out) :: h_event
    type(error_t), intent(inout) :: err
    real(dp), allocatable :: margin(:)
    type(advancement_result_t) :: res
    real(dp), allocatable :: pair_time(:)
    logical, allocatable :: pair_touches(:)
    integer :: n, i, j, k

    n = bodies%n_owned + bodies%n_ghost
    h_event = h
    self%n_events = 0
    if (n < 2) return
    ! The pairs of prepare, unless the contact pass made a body travel further than the
    ! margin it was entered with (or the grid cut the step since): then the grid again,
    ! keeping the gaps already known.
    allocate (margin(n))
    do i = 1, n
      ! The bounding sphere does not move when the body turns: only translation grows it.
      margin(i) = 0.0_dp
      if (.not. bodies%fixed(i)) margin(i) = norm2(bodies%v(:, i))*h + 0.5_dp*norm2(flight%acceleration(i, gravity))*h*h
    end do
    if (.not. allocated(self%grid_margin)) then
      call self%prepare(bodies, shapes, flight, h, gravity, err)
    else if (size(self%grid_margin) < n) then
      call self%prepare(bodies, shapes, flight, h, gravity, err)
    else if (any(margin > self%grid_margin(1:n)) .or. &
             any([(turning_reach(shapes, bodies, i)*h > self%turn(i), i=1, n)])) then
      call self%prepare(bodies, shapes, flight, h, gravity, err, margins=max(margin, self%grid_margin(1:n)))
    end if
    if (err%failed()) return
    if (self%n_pairs == 0) return

    allocate (pair_time(self%n_pairs), pair_touches(self%n_pairs))
    pair_touches = .false.
    pair_time = huge(1.0_dp)
    ! Gaps at the step's start: prepare's, after the distance correction.
    do k = 1, self%n_pairs
      if (self%pair_far(k)) cycle
      i = self%pairs(1, k)
      j = self%pairs(2, k)
      call self%advance_candidate(bodies, shapes, flight, gravity, config, time_now, k, h_event, self%max_iterations, &
                                  res)
      if (res%capped) self%stats%capped = self%stats%capped + 1
      if (res%contact .or. res%capped) then
        pair_time(k) = res%time
        ! A capped pair only shortens the step (it is still above its floor): nothing to
        ! resolve there, unless it cannot advance at all (the stall guard counts those).
        pair_touches(k) = res%contact .or. res%time == 0.0_dp
        if (res%time == 0.0_dp) then
          self%stalled_pair = [bodies%gid(i), bodies%gid(j)]
        end if
        ! Later pairs only need to be advanced up to the earliest time found so far.
        h_event = min(h_event, res%time)
      end if
    end do
    ! The pairs that reach contact at the chosen time (capped ones only shorten the step).
    self%n_events = count(pair_time <= h_event .and. pair_touches)
    if (allocated(self%event_pairs)) deallocate (self%event_pairs)
    allocate (self%event_pairs(2, self%n_events))
    self%n_events = 0
    do k = 1, self%n_pairs
      if (pair_time(k) <= h_event .and. pair_touches(k)) then
        self%n_events = self%n_events + 1
        self%event_pairs(:, self%n_events) = self%pairs(:, k)
      end if
    end do
  end subroutine stage_earliest_contact

  !> Time of contact of candidate pair k of the step's table over [0, step] from time_now
  !> (bodies at time_now), by conservative advancement, with what the pair is: solved by the
  !> contact pass (an inelastic pair may come down to the settling floor), in the band and
  !> receding (it may settle), hovering just above the band, or an approach to the target;
  !> turning pairs start from the second-order safe time (plane_bound) and receding ones are
  !> re-tested along the step (extend_receding). One pair's part of earliest_contact, and what
  !> the local event loop computes for a pair whose certificate is due.
  module subroutine stage_advance_candidate(self, bodies, shapes, flight, gravity, config, time_now, k, step, &
                                            max_iterations, res)
    class(collision_stage_t), intent(inout), target :: self
    type(bodies_t), intent(inout), target :: bodies
    type(shape_library_t), intent(in), target :: shapes
    type(free_flight_t), intent(inout), target :: flight
    real(dp), intent(in) :: gravity(3), time_now
    type(integrator_config_t), intent(in) :: config
    integer, intent(in) :: k
    real(dp), intent(in) :: step          !< [s] from time_now
    integer, intent(in) :: max_iterations
    type(advancement_result_t), intent(out) :: res
    type(pair_oracle_t) :: oracle
    type(pair_motion_t) :: motion
    real(dp) :: gap0, normal0(3), safe, floor
    logical :: hovering, solved, receding
    integer :: i, j
    i = self%pairs(1, k)
    j = self%pairs(2, k)
    gap0 = self%pair_gap0(k)
    normal0 = self%pair_normal(:, k)
    ! Inelastic pairs the contact pass solved (in the band, or speculative: not yet touching),
    ! still above the floor: their contact points may approach only as fast as closes them to
    ! the band in the step, and whatever the solve left is bounded below as it is.
    solved = self%pair_in_pass(k) .and. gap0 > 0.5_dp*self%target + self%tolerance
    if (solved) solved = self%materials%pair_restitution(bodies%group_id(i), bodies%group_id(j)) <= 0.0_dp
    motion = pair_motion(shapes, bodies, flight, i, j, gravity)
    ! In the contact band, measure whether any contact point really approaches: the bound's
    ! turning term (Omega r) says "may approach" for every spinning pair in contact.
    ! Receding pairs settle towards the floor instead of stopping the run (pairs already
    ! near the floor were opened by correct_distances at the step's start).
    receding = .false.
    if (.not. (gap0 > self%target + self%tolerance .or. solved)) then
      if (band_rate(motion, normal0) > self%velocity_tolerance) &
        receding = .not. approaching(self, bodies, shapes, i, j, gap0, normal0)
    end if
    oracle%flight => flight
    oracle%bodies => bodies
    oracle%shapes => shapes
    oracle%memo => self%memo
    oracle%config = config
    oracle%time_now = time_now
    ! times of contact on the exact propagator made canonical: every pose is a function of
    ! the anchor and the absolute time alone (canonical_crossing)
    oracle%canonical = flight%exact
    oracle%origin = time_now
    oracle%gravity = gravity
    oracle%i = i
    oracle%j = j
    oracle%min_gap = huge(1.0_dp)
    ! The oracle's own bounds (turning_bound, plane_bound from each iterate) for convex pairs
    ! on the exact propagator; not for pairs the contact pass solved: those come down to the
    ! settling floor only as an event, and the tighter bound brings more of them there
    ! within their island's step (each such micro-impact cuts the island: five 64-cube pours
    ! at the auto min_separation made 2079 impacts instead of 1781, 1.21x the wall time),
    ! while the loose bound's capped crawl leaves them to the island's next contact pass.
    oracle%directional = flight%exact .and. motion%convex .and. .not. solved
    oracle%gjk = convex_pair(shapes, bodies, i, j)
    ! Turning bodies: the second-order bound (plane_bound) skips the part of the step in
    ! which the pair provably stays above the band (or, settling in the band, above the
    ! floor). A pair hovering just above the band (within one target, its centres closing
    ! slower than the rest speed: a tumbling body about to rest) may come down to 3/4 of
    ! the target instead, or the first-order bound would crawl towards the band in tiny
    ! steps; such a contact is a resting one, not an impact whose timing matters.
    safe = 0.0_dp
    hovering = .false.
    if (solved) then
      ! A solved pair may come down to the settling floor; only there is it an event.
      ! Turning pairs: the second-order bound, re-tested along the step (extend_receding),
      ! with the first-order bound crawl-limited.
      if (motion%omega_r_a + motion%omega_r_b > 0.0_dp) then
        safe = plane_safe_time(shapes, bodies, flight, gravity, i, j, normal0, 0.5_dp*self%target + self%tolerance, &
                               step)
        if (safe > 0.0_dp) self%stats%plane_skips = self%stats%plane_skips + 1
      end if
      call advance_pair(oracle, motion, gap0, normal0, step, 0.5_dp*self%target, self%tolerance, &
                        0.5_dp*self%target, self%velocity_tolerance, max_iterations, res, safe_time=safe, &
                        hovering=.true.)
    else
      if (motion%omega_r_a + motion%omega_r_b > 0.0_dp) then
        if (gap0 > self%target + self%tolerance) then
          floor = self%target + self%tolerance
          hovering = gap0 < 2.0_dp*self%target .and. dot_product(normal0, motion%v_a - motion%v_b) <= self%rest_speed
          if (hovering) floor = 0.75_dp*self%target
          safe = plane_safe_time(shapes, bodies, flight, gravity, i, j, normal0, floor, step)
        else if (receding .or. band_rate(motion, normal0) <= self%velocity_tolerance) then
          safe = plane_safe_time(shapes, bodies, flight, gravity, i, j, normal0, 0.5_dp*self%target, step)
        end if
        if (safe > 0.0_dp) self%stats%plane_skips = self%stats%plane_skips + 1
      end if
      call advance_pair(oracle, motion, gap0, normal0, step, self%target, self%tolerance, 0.5_dp*self%target, &
                        self%velocity_tolerance, max_iterations, res, receding=receding, safe_time=safe, &
                        hovering=hovering)
    end if
    self%stats%advancement_iterations = self%stats%advancement_iterations + res%iterations
    self%stats%convex_bounds = self%stats%convex_bounds + oracle%bounds
    self%stats%min_separation = min(self%stats%min_separation, oracle%min_gap)
    if ((receding .or. solved) .and. (res%contact .or. res%capped) .and. res%time > 0.0_dp .and. &
        res%time < step .and. flight%exact) then
      call extend_receding(self, bodies, shapes, flight, gravity, config, time_now, i, j, step, res, solved)
    end if
  end subroutine stage_advance_candidate

  !> A pair in the band whose contact points recede (a tumbling body sliding or rolling
  !> over another) advances only to its second-order safe time, a few microseconds when the
  !> bodies turn fast, and is then still in the band: without more, every such pair ended
  !> the global step there (three quarters of the steps of a landing pile of tetrahedra).
  !> The safe time was computed from the step's start; at its end the state is known
  !> exactly (the propagator's anchored flight), so the same test is repeated from there:
  !> the gap measured, the contact points still receding, a new safe time down to the same
  !> floor. At most max_extensions times; the pair stops where a test fails (as before,
  !> an event there). Nothing is assumed beyond what the first test checked at t = 0.
  !> solved: the pair was solved by the contact pass (an inelastic pair): it may come down
  !> to the floor from anywhere, at any speed the bound allows, so neither leaving the band
  !> nor an approach ends the re-tests; only the floor does.
  subroutine extend_receding(self, bodies, shapes, flight, gravity, config, time_now, i, j, h_limit, res, solved)
    type(collision_stage_t), intent(inout) :: self
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    real(dp), intent(in) :: gravity(3), time_now, h_limit
    type(integrator_config_t), intent(in) :: config
    integer, intent(in) :: i, j
    type(advancement_result_t), intent(inout) :: res
    logical, intent(in), optional :: solved
    integer, parameter :: max_extensions = 8
    logical :: floor_only
    real(dp) :: saved_x(3, 2), saved_q(4, 2), saved_v(3, 2), saved_w(3, 2), t, gap, normal(3), safe
    real(dp) :: x_t(3), q_t(4), w_t(3)
    integer :: extension, pair(2), b
    floor_only = .false.
    if (present(solved)) floor_only = solved
    pair = [i, j]
    do b = 1, 2
      saved_x(:, b) = bodies%x(:, pair(b))
      saved_q(:, b) = bodies%q(:, pair(b))
      saved_v(:, b) = bodies%v(:, pair(b))
      saved_w(:, b) = bodies%w(:, pair(b))
    end do
    t = res%time
    do extension = 1, max_extensions
      ! The two bodies as the propagator will have them at t (the others do not enter).
      do b = 1, 2
        if (bodies%fixed(pair(b))) cycle
        ! (anchored at the step's start by the first call, from the unchanged state)
        call flight%pose_at(bodies, pair(b), time_now, t, gravity, config, x_t, q_t, w_t)
        bodies%x(:, pair(b)) = x_t
        bodies%q(:, pair(b)) = q_t
        bodies%w(:, pair(b)) = w_t
        bodies%v(:, pair(b)) = saved_v(:, b) + t*flight%acceleration(pair(b), gravity)
      end do
      call self%memo%pair_gap(shapes, bodies, i, j, bodies%x(:, i), bodies%q(:, i), bodies%x(:, j), bodies%q(:, j), &
                              gap, normal)
      self%stats%pair_tests = self%stats%pair_tests + 1
      self%stats%min_separation = min(self%stats%min_separation, gap)
      if (gap <= 0.5_dp*self%target + self%tolerance) exit
      if (.not. floor_only) then
        if (gap > self%target + self%tolerance) exit
        ! Contact points closing slower than the rest speed (rolling brings them down at second
        ! order) may settle towards the floor, as at the step's start: the plane bound holds for
        ! any motion, so it bounds them. Faster ones are impacts: the step ends for them.
        if (approaching(self, bodies, shapes, i, j, gap, normal, self%rest_speed)) exit
      end if
      safe = plane_safe_time(shapes, bodies, flight, gravity, i, j, normal, 0.5_dp*self%target, h_limit - t)
      if (safe <= 0.0_dp) exit
      self%stats%plane_skips = self%stats%plane_skips + 1
      t = min(t + safe, h_limit)
      if (t >= h_limit) exit
    end do
    do b = 1, 2
      bodies%x(:, pair(b)) = saved_x(:, b)
      bodies%q(:, pair(b)) = saved_q(:, b)
      bodies%v(:, pair(b)) = saved_v(:, b)
      bodies%w(:, pair(b)) = saved_w(:, b)
    end do
    if (t >= h_limit) then
      res%contact = .false.
      res%capped = .false.
      res%time = h_limit
    else
      res%time = t
      ! a solved pair stops at the floor (an event), or where the bound could not go on
      ! while it was still above the floor (a shorter step, nothing to resolve)
      if (floor_only) then
        res%contact = gap <= 0.5_dp*self%target + self%tolerance
        res%capped = .not. res%contact
      end if
    end if
  end subroutine extend_receding

  !> Closing rate of the pair's bound at the step's start (as time_of_contact forms it).
  pure real(dp) function band_rate(motion, n)
    type(pair_motion_t), intent(in) :: motion
    real(dp), intent(in) :: n(3)
    if (motion%convex) then
      band_rate = dot_product(n, motion%v_a - motion%v_b) + motion%omega_r_a + motion%omega_r_b
    else
      band_rate = norm2(motion%v_a - motion%v_b) + motion%omega_r_a + motion%omega_r_b
    end if
  end function band_rate

  !> Does any contact point of the pair approach? The same contact points as resolve
  !> builds (pair_contact_points), so that a pair resolve has made non-approaching is seen
  !> as such here.
  !> speed [m/s], when present: approaching means faster than this (default: the settle speed).
  logical function approaching(self, bodies, shapes, i, j, gap, normal, speed)
    type(collision_stage_t), intent(inout) :: self
    type(bodies_t), intent(in) :: bodies
    type(shape_library_t), intent(in) :: shapes
    integer, intent(in) :: i, j
    real(dp), intent(in) :: gap, normal(3)
    real(dp), intent(in), optional :: speed
    type(contact_t), allocatable :: points(:)
    integer(i8), allocatable :: keys(:, :)
    integer :: c, n_points
    real(dp) :: limit
    limit = self%settle_speed
    if (present(speed)) limit = speed
    n_points = 0
    call pair_contact_points(shapes, bodies, i, j, gap, normal, self%contact_tolerance, points, keys, n_points, &
                             self%features)
    approaching = .false.
    do c = 1, n_points
      if (normal_velocity(bodies, points(c)) < -limit) then
        approaching = .true.
        return
      end if
    end do
  end function approaching

  !> The bound's inputs: velocities and accelerations at the step's start and angular
  !> speed bound times the largest radius (zero for analytic spheres: turning moves none of
  !> their surface).
  function pair_motion(shapes, bodies, flight, i, j, gravity) result(motion)
    type(shape_library_t), intent(in) :: shapes
    type(bodies_t), intent(in) :: bodies
    type(free_flight_t), intent(in) :: flight
    integer, intent(in) :: i, j
    real(dp), intent(in) :: gravity(3)
    type(pair_motion_t) :: motion
    motion%v_a = bodies%v(:, i)
    motion%v_b = bodies%v(:, j)
    motion%a_a = merge(0.0_dp, 1.0_dp, bodies%fixed(i))*flight%acceleration(i, gravity)
    motion%a_b = merge(0.0_dp, 1.0_dp, bodies%fixed(j))*flight%acceleration(j, gravity)
    motion%omega_r_a = turning_reach(shapes, bodies, i)
    motion%omega_r_b = turning_reach(shapes, bodies, j)
    motion%convex = shapes%shapes(bodies%shape_id(i))%convex .and. shapes%shapes(bodies%shape_id(j))%convex
  end function pair_motion

  subroutine oracle_gap_at(self, t, gap, normal)
    class(pair_oracle_t), intent(inout) :: self
    real(dp), intent(in) :: t
    real(dp), intent(out) :: gap, normal(3)
    real(dp) :: xi(3), qi(4), xj(3), qj(4)
    real(dp) :: wi(3), wj(3)
    call self%flight%pose_at(self%bodies, self%i, self%time_now, t, self%gravity, self%config, xi, qi, wi)
    call self%flight%pose_at(self%bodies, self%j, self%time_now, t, self%gravity, self%config, xj, qj, wj)
    call self%memo%pair_gap(self%shapes, self%bodies, self%i, self%j, xi, qi, xj, qj, gap, normal)
    self%min_gap = min(self%min_gap, gap)
    self%t_pose = t
    self%x_pose(:, 1) = xi
    self%x_pose(:, 2) = xj
    self%q_pose(:, 1) = qi
    self%q_pose(:, 2) = qj
    self%w_pose(:, 1) = wi
    self%w_pose(:, 2) = wj
  end subroutine oracle_gap_at

  !> GJK's certified lower bound on the gap at time_now + t (convex_distance), the poses kept
  !> as gap_at keeps them (the directional bound starts from them); the exact query when the
  !> pair is not one for GJK or GJK cannot certify a separation (touching hulls).
  subroutine oracle_lower_gap_at(self, t, gap, normal, exact)
    class(pair_oracle_t), intent(inout) :: self
    real(dp), intent(in) :: t
    real(dp), intent(out) :: gap, normal(3)
    logical, intent(out) :: exact
    real(dp) :: xi(3), qi(4), xj(3), qj(4), wi(3), wj(3)
    logical :: certified
    exact = .true.
    if (.not. self%gjk) then
      call self%gap_at(t, gap, normal)
      return
    end if
    call self%flight%pose_at(self%bodies, self%i, self%time_now, t, self%gravity, self%config, xi, qi, wi)
    call self%flight%pose_at(self%bodies, self%j, self%time_now, t, self%gravity, self%config, xj, qj, wj)
    call convex_pair_bound(self%shapes, self%bodies, self%i, self%j, xi, qi, xj, qj, gap, normal, certified)
    if (.not. certified) then
      call self%gap_at(t, gap, normal)
      return
    end if
    exact = .false.
    self%bounds = self%bounds + 1
    self%t_pose = t
    self%x_pose(:, 1) = xi
    self%x_pose(:, 2) = xj
    self%q_pose(:, 1) = qi
    self%q_pose(:, 2) = qj
    self%w_pose(:, 1) = wi
    self%w_pose(:, 2) = wj
  end subroutine oracle_lower_gap_at

  !> Closest points at the absolute time t_abs: the poses at t_abs + 0 from the anchors, so
  !> the same bits whatever time_now is (exact propagator).
  subroutine oracle_gap_at_time(self, t_abs, gap, normal)
    class(pair_oracle_t), intent(inout) :: self
    real(dp), intent(in) :: t_abs
    real(dp), intent(out) :: gap, normal(3)
    real(dp) :: xi(3), qi(4), xj(3), qj(4)
    call self%flight%pose_at(self%bodies, self%i, t_abs, 0.0_dp, self%gravity, self%config, xi, qi)
    call self%flight%pose_at(self%bodies, self%j, t_abs, 0.0_dp, self%gravity, self%config, xj, qj)
    call self%memo%pair_gap(self%shapes, self%bodies, self%i, self%j, xi, qi, xj, qj, gap, normal)
    ! (not sampled into min_gap: canonical_crossing probes up to a cell, 9.1e-13 s, past the
    ! crossing, where a body at 1e4 m/s is 9 nm closer than any time it commits to)
  end subroutine oracle_gap_at_time
  !> The directional bound (turning_bound) from the poses at t: how long the pair's
  !> separation along normal stays above `above` [s] (0: no such bound for this pair).
  real(dp) function oracle_turning_time(self, t, normal, above, horizon) result(dt)
    class(pair_oracle_t), intent(inout) :: self
    real(dp), intent(in) :: t, normal(3), above, horizon
    type(turning_body_t) :: body_a, body_b
    type(plane_body_t) :: plane_a, plane_b
    real(dp) :: x(3), q(4), w(3)
    dt = 0.0_dp
    if (.not. self%directional) return
    if (self%shapes%shapes(self%bodies%shape_id(self%i))%kind == SHAPE_SPHERE .and. &
        self%shapes%shapes(self%bodies%shape_id(self%j))%kind == SHAPE_SPHERE) return
    if (t /= self%t_pose) then
      ! (at the step's start: no query was made yet)
      call self%flight%pose_at(self%bodies, self%i, self%time_now, t, self%gravity, self%config, x, q, w)
      self%x_pose(:, 1) = x
      self%q_pose(:, 1) = q
      self%w_pose(:, 1) = w
      call self%flight%pose_at(self%bodies, self%j, self%time_now, t, self%gravity, self%config, x, q, w)
      self%x_pose(:, 2) = x
      self%q_pose(:, 2) = q
      self%w_pose(:, 2) = w
      self%t_pose = t
    end if
    body_a = side(self%i, 1)
    body_b = side(self%j, 2)
    associate (sa => self%shapes%shapes(self%bodies%shape_id(self%i)), &
               sb => self%shapes%shapes(self%bodies%shape_id(self%j)))
      if (sa%kind == SHAPE_SPHERE .and. sb%kind == SHAPE_SPHERE) then
        return              ! (the first-order bound is already exact for two spheres)
      else if (sa%kind == SHAPE_SPHERE) then
        dt = directional_time(body_a, sphere_node, body_b, sb%mesh%nodes, normal, above, horizon)
      else if (sb%kind == SHAPE_SPHERE) then
        dt = directional_time(body_a, sa%mesh%nodes, body_b, sphere_node, normal, above, horizon)
      else
        dt = directional_time(body_a, sa%mesh%nodes, body_b, sb%mesh%nodes, normal, above, horizon)
      end if
      ! Above `above` along normal now (dt > 0): the plane bound from here is safe too, with
      ! either body as the plane (a face turning under the other's corner moves there only
      ! as fast as its turning carries that corner's foot, not as fast as its far edge).
      if (dt > 0.0_dp .and. dt < horizon) then
        plane_a = plane_side(self%i, 1)
        plane_b = plane_side(self%j, 2)
        dt = max(dt, plane_time(sa, plane_a, sb, plane_b, normal, above, horizon))
        if (.not. (plane_a%world_fixed .or. plane_b%world_fixed)) &
          dt = max(dt, plane_time(sb, plane_b, sa, plane_a, -normal, above, horizon))
      end if
    end associate
  contains
    !> Body k (slot s of the cached poses) at t, as the plane bound needs it.
    function plane_side(k, s) result(body)
      integer, intent(in) :: k, s
      type(plane_body_t) :: body
      if (self%bodies%fixed(k)) then
        body = plane_body_at(self%x_pose(:, s), self%q_pose(:, s), [0.0_dp, 0.0_dp, 0.0_dp], [0.0_dp, 0.0_dp, 0.0_dp], &
                             self%bodies%inertia(:, k), .true., self%shapes%shapes(self%bodies%shape_id(k)))
      else
        body = plane_body_at(self%x_pose(:, s), self%q_pose(:, s), self%w_pose(:, s), &
                             self%bodies%v(:, k) + t*self%flight%acceleration(k, self%gravity), self%bodies%inertia(:, k), &
                             .false., self%shapes%shapes(self%bodies%shape_id(k)))
        body%a = self%flight%acceleration(k, self%gravity)
      end if
    end function plane_side

    !> Body k (slot s of the cached poses) at t, as the bound needs it.
    function side(k, s) result(body)
      integer, intent(in) :: k, s
      type(turning_body_t) :: body
      real(dp) :: v(3), a(3), radius, reach
      associate (sk => self%shapes%shapes(self%bodies%shape_id(k)))
        if (sk%kind == SHAPE_SPHERE) then
          radius = sk%radius
          reach = 0.0_dp
        else
          radius = 0.0_dp
          reach = sk%bounding_radius
        end if
      end associate
      if (self%bodies%fixed(k)) then
        body = turning_body(self%x_pose(:, s), self%q_pose(:, s), [0.0_dp, 0.0_dp, 0.0_dp], [0.0_dp, 0.0_dp, 0.0_dp], &
                            [0.0_dp, 0.0_dp, 0.0_dp], self%bodies%inertia(:, k), 0.0_dp, radius)
      else
        a = self%flight%acceleration(k, self%gravity)
        v = self%bodies%v(:, k) + t*a
        body = turning_body(self%x_pose(:, s), self%q_pose(:, s), self%w_pose(:, s), v, a, self%bodies%inertia(:, k), &
                            reach, radius)
      end if
    end function side
  end function oracle_turning_time

end submodule collision_stage_advance
