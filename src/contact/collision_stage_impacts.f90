!> Impacts at the end of a step: the contact groups of the event pairs and their simultaneous
!> impulses (impulse_solver, with friction; groups too large for the exact solve by projected
!> Gauss-Seidel), and the event log (resolve); after the step, sleeping (settle, wake_all),
!> and dropping the events when another rank's contact came first (drop_events).
!> A submodule: it reads the stage's event pairs and pair table and fills its contact list.
submodule (collision_stage) collision_stage_impacts
  use error_status, only: ERR_NUMERIC
  use string_utils, only: str
  use impulse_solver, only: resolve_impacts, normal_velocity, contact_groups, group_members
  use contact_solver, only: solve_contacts_pgs
  use pair_geometry, only: pair_gap, gap_lower_bound, pair_contact_points, bounding_sphere_boxes
  implicit none

contains

  !> After the bodies moved to the event: contact points of every pair in contact (the
  !> event pairs, and every candidate pair touching them, so a group is solved together),
  !> simultaneous impulses, and the anchors of the bodies whose velocities changed.
  !> Contacts approaching slower than the rest speed are inelastic; with friction, the
  !> normal impulses bound the friction impulses of the same impact (Coulomb's cone), and if
  !> friction makes a contact approach again the inelastic projection closes the loop.
  !> time [s], when present: the event's time, for the event log (log_events).
  module subroutine stage_resolve(self, bodies, shapes, flight, h_event, h_planned, err, time)
    class(collision_stage_t), intent(inout) :: self
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    real(dp), intent(in) :: h_event     !< the step taken [s]
    real(dp), intent(in) :: h_planned   !< the step before the contact cut it [s]
    type(error_t), intent(inout) :: err
    real(dp), intent(in), optional :: time
    integer :: i, c, n_contacts, n_moving
    integer, allocatable :: moving(:), side(:, :)
    real(dp), allocatable :: v_old(:, :), w_old(:, :), normal_impulse(:), friction_impulse(:, :)
    logical, allocatable :: large(:)
    logical :: woke

    if (self%n_events == 0) return
    self%stats%events = self%stats%events + 1
    ! Steps of no length, or of a length that cannot move the clock (1e-15 of the step it
    ! replaced), count towards the stall guard.
    if (h_event <= 1.0e-15_dp*max(h_planned, tiny(1.0_dp))) then
      self%zero_steps = self%zero_steps + 1
    else
      self%zero_steps = 0
    end if
    ! Checked here, before the returns below: a step of length 0 whose event pair is not in
    ! the band (no contact point, nothing solved) is the same stall, and used to repeat
    ! forever unreported.
    if (self%zero_steps > 1000) then
      call err%set(ERR_NUMERIC, 'collision loop stalled: 1000 steps of zero length at a persistent contact '// &
                   'between bodies '//str(self%stalled_pair(1))//' and '//str(self%stalled_pair(2))// &
                   ' (smallest separation '//str(self%stats%min_separation)//' m)')
      return
    end if
    ! Every candidate pair within the contact band joins, so touching neighbours (a cradle,
    ! a box on four corners) are solved in one simultaneous group.
    call gather_contacts(self, bodies, shapes, n_contacts)
    call keep_event_groups(self, bodies, n_contacts)
    if (n_contacts == 0) return
    ! A body that hits a sleeping island wakes it: the impact is solved with it awake.
    call self%sleep%wake_touching(bodies, flight, self%contacts(1:n_contacts), woke)
    if (woke) then
      call collect_band_contacts(self, bodies, shapes, flight, n_contacts, err)
      if (err%failed()) return
      call keep_event_groups(self, bodies, n_contacts)
    end if
    self%stats%contacts = self%stats%contacts + n_contacts
    do c = 1, n_contacts
      if (normal_velocity(bodies, self%contacts(c)) > -self%rest_speed) self%contacts(c)%restitution = 0.0_dp
    end do
    ! the bodies the impulses can change, and their velocities before
    call group_members(bodies, self%contacts(1:n_contacts), moving, n_moving, side)
    allocate (v_old(3, n_moving), w_old(3, n_moving))
    do c = 1, n_moving
      v_old(:, c) = bodies%v(:, moving(c))
      w_old(:, c) = bodies%w(:, moving(c))
    end do
    allocate (normal_impulse(n_contacts), large(n_contacts))
    call resolve_impacts(bodies, self%contacts(1:n_contacts), self%velocity_tolerance, self%max_rounds, &
                         self%impulses, err, normal_impulse, self%resting%projection_limit, large)
    if (err%failed()) return
    ! Groups too large for the exact solve (a pile in contact): inelastic, with friction, by
    ! projected Gauss-Seidel; their normal impulses are left out of the friction step below,
    ! which this solve has done for them.
    if (any(large)) call solve_large_groups(self, bodies, pack(self%contacts(1:n_contacts), large))
    if (any(self%contacts(1:n_contacts)%friction > 0.0_dp) .and. any(normal_impulse > 0.0_dp)) then
      allocate (friction_impulse(3, n_contacts))
      friction_impulse = 0.0_dp
      call solve_contacts_pgs(bodies, self%contacts(1:n_contacts), friction_impulse, self%resting%tolerance, &
                              self%resting%max_sweeps, self%impact_friction, fixed_normal=normal_impulse)
      if (any([(normal_velocity(bodies, self%contacts(c)) < -self%velocity_tolerance, c=1, n_contacts)])) then
        self%contacts(1:n_contacts)%restitution = 0.0_dp
        call resolve_impacts(bodies, self%contacts(1:n_contacts), self%velocity_tolerance, self%max_rounds, &
                             self%impulses, err, max_group=self%resting%projection_limit, large=large)
        if (err%failed()) return
        if (any(large)) call solve_large_groups(self, bodies, pack(self%contacts(1:n_contacts), large))
      end if
    end if
    call remove_residual_approach(self, bodies, self%contacts(1:n_contacts))
    do c = 1, n_moving
      i = moving(c)
      ! (ghost rows too: a cross-rank impact, whose new anchors go to their owners)
      if (any(v_old(:, c) /= bodies%v(:, i)) .or. any(w_old(:, c) /= bodies%w(:, i))) then
        call flight%release(i)
        if (self%log_events .and. present(time)) call log_impulse(self, bodies, i, time, v_old(:, c), w_old(:, c))
      end if
    end do
  end subroutine stage_resolve

  !> One row of the event log: body i's linear and angular impulse at an event at time.
  subroutine log_impulse(self, bodies, i, time, v_old, w_old)
    type(collision_stage_t), intent(inout) :: self
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: i
    real(dp), intent(in) :: time, v_old(3), w_old(3)
    real(dp), allocatable :: grown(:, :)
    if (.not. allocated(self%log_rows)) allocate (self%log_rows(8, 256))
    if (self%n_log == size(self%log_rows, 2)) then
      allocate (grown(8, 2*self%n_log))
      grown(:, 1:self%n_log) = self%log_rows(:, 1:self%n_log)
      call move_alloc(grown, self%log_rows)
    end if
    self%n_log = self%n_log + 1
    self%log_rows(1, self%n_log) = time
    self%log_rows(2, self%n_log) = real(bodies%gid(i), dp)
    self%log_rows(3:5, self%n_log) = bodies%mass(i)*(bodies%v(:, i) - v_old)
    self%log_rows(6:8, self%n_log) = bodies%world_inertia_apply(i, bodies%w(:, i)) - bodies%world_inertia_apply(i, w_old)
  end subroutine log_impulse

  !> An impact inside a group of contacts too large for the exact solve: inelastic, with
  !> Coulomb friction, by projected Gauss-Seidel from zero impulses (dissipative, and every
  !> contact left approaching is caught by remove_residual_approach and, past that, by the
  !> next time of contact).
  subroutine solve_large_groups(self, bodies, contacts)
    type(collision_stage_t), intent(inout) :: self
    type(bodies_t), intent(inout) :: bodies
    type(contact_t), intent(in) :: contacts(:)
    real(dp), allocatable :: impulse(:, :)
    allocate (impulse(3, size(contacts)))
    impulse = 0.0_dp
    call solve_contacts_pgs(bodies, contacts, impulse, self%resting%tolerance, self%resting%max_sweeps, &
                            self%impact_friction)
  end subroutine solve_large_groups

  !> Safety net after the impulse solvers: the exact projection can stop at its iteration cap
  !> on rank-deficient groups (many contact points on few bodies), leaving contacts that
  !> still approach, which would stop the next step at once. Frictionless projected
  !> Gauss-Seidel (monotone, convergent for any positive semi-definite contact matrix)
  !> removes what is left down to a thousandth of the settle speed.
  subroutine remove_residual_approach(self, bodies, contacts)
    type(collision_stage_t), intent(inout) :: self
    type(bodies_t), intent(inout) :: bodies
    type(contact_t), intent(in) :: contacts(:)
    type(contact_t), allocatable :: frictionless(:)
    real(dp), allocatable :: impulse(:, :)
    integer :: c
    if (.not. any([(normal_velocity(bodies, contacts(c)) < -self%settle_speed, c=1, size(contacts))])) return
    frictionless = contacts
    frictionless%friction = 0.0_dp
    allocate (impulse(3, size(contacts)))
    impulse = 0.0_dp
    call solve_contacts_pgs(bodies, frictionless, impulse, 1.0e-3_dp*self%settle_speed, 5000, self%residual_pgs)
  end subroutine remove_residual_approach

  !> Keeps, of self%contacts(1:n_contacts), the contact groups (connected through moving
  !> bodies) that hold a moving body of an event pair: an impact is simultaneous with what
  !> touches it, not with every pair that happens to be in the band elsewhere in the scene
  !> (those reach their own events at their own times). This is also what the local event
  !> loop solves at an impact, so the two loops find the same impulses.
  subroutine keep_event_groups(self, bodies, n_contacts)
    type(collision_stage_t), intent(inout) :: self
    type(bodies_t), intent(in) :: bodies
    integer, intent(inout) :: n_contacts
    integer, allocatable :: group_start(:), group_list(:), event_bodies(:)
    logical, allocatable :: keep(:)
    integer :: n_groups, g, k, c, e
    if (n_contacts == 0) return
    allocate (event_bodies(2*self%n_events))
    e = 0
    do k = 1, self%n_events
      do c = 1, 2
        if (bodies%fixed(self%event_pairs(c, k))) cycle
        e = e + 1
        event_bodies(e) = self%event_pairs(c, k)
      end do
    end do
    call contact_groups(bodies, self%contacts(1:n_contacts), group_start, group_list, n_groups)
    allocate (keep(n_contacts))
    keep = .false.
    do g = 1, n_groups
      associate (members => group_list(group_start(g):group_start(g + 1) - 1))
        do k = 1, size(members)
          if (any(event_bodies(1:e) == self%contacts(members(k))%a) .or. &
              any(event_bodies(1:e) == self%contacts(members(k))%b)) then
            keep(members) = .true.
            exit
          end if
        end do
      end associate
    end do
    if (all(keep)) return
    k = count(keep)
    self%contacts(1:k) = pack(self%contacts(1:n_contacts), keep)
    n_contacts = k
  end subroutine keep_event_groups

  !> Candidate pairs from one ring of a fresh grid and every contact point within the
  !> contact band, into self%contacts(1:n_contacts). Sleeping islands a moving body touches
  !> wake, and the contacts are gathered again with them awake (their pairs with each other
  !> were static-static pairs, never listed, while they slept).
  subroutine collect_band_contacts(self, bodies, shapes, flight, n_contacts, err)
    type(collision_stage_t), intent(inout) :: self
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    integer, intent(out) :: n_contacts
    type(error_t), intent(inout) :: err
    real(dp), allocatable :: lower(:, :), upper(:, :)
    integer :: n, round
    logical :: woke
    n = bodies%n_owned + bodies%n_ghost
    n_contacts = 0
    allocate (lower(3, n), upper(3, n))
    call bounding_sphere_boxes(shapes, bodies, n, lower, upper)
    ! Each round wakes at least one island: at most as many rounds as islands asleep.
    do round = 1, n + 1
      call self%grid%build(n, lower, upper, bodies%fixed(1:n), err)
      if (err%failed()) return
      call self%grid%candidate_pairs(1, [self%target + self%tolerance + self%contact_tolerance], self%pairs, &
                                     self%n_pairs, err, n_owned=bodies%n_owned)
      if (err%failed()) return
      call gather_contacts(self, bodies, shapes, n_contacts)
      call self%sleep%wake_touching(bodies, flight, self%contacts(1:n_contacts), woke)
      if (.not. woke) exit
    end do
  end subroutine collect_band_contacts

  !> Contact points of every candidate pair within the contact band, gathered into
  !> self%contacts(1:n_contacts) with their keys (restitution and friction of the pair).
  subroutine gather_contacts(self, bodies, shapes, n_contacts)
    type(collision_stage_t), intent(inout) :: self
    type(bodies_t), intent(in) :: bodies
    type(shape_library_t), intent(in) :: shapes
    integer, intent(out) :: n_contacts
    integer :: k, i, j, first
    real(dp) :: gap, normal(3), band
    n_contacts = 0
    band = self%target + self%tolerance + self%contact_tolerance
    do k = 1, self%n_pairs
      i = self%pairs(1, k)
      j = self%pairs(2, k)
      if (bodies%fixed(i) .and. bodies%fixed(j)) cycle
      if (gap_lower_bound(shapes, bodies, i, j, band) > band) cycle
      call self%memo%pair_gap(shapes, bodies, i, j, bodies%x(:, i), bodies%q(:, i), bodies%x(:, j), bodies%q(:, j), &
                              gap, normal)
      self%stats%min_separation = min(self%stats%min_separation, gap)
      if (gap > band) cycle
      first = n_contacts + 1
      call pair_contact_points(shapes, bodies, i, j, gap, normal, self%contact_tolerance, self%contacts, self%keys, &
                               n_contacts, self%features)
      self%contacts(first:n_contacts)%restitution = &
        self%materials%pair_restitution(bodies%group_id(i), bodies%group_id(j))
      self%contacts(first:n_contacts)%friction = self%materials%pair_friction(bodies%group_id(i), bodies%group_id(j))
    end do
  end subroutine gather_contacts

  !> After a step of h [s]: islands quiet for long enough fall asleep (sleeping).
  module subroutine stage_settle(self, bodies, shapes, flight, h)
    class(collision_stage_t), intent(inout) :: self
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    real(dp), intent(in) :: h
    if (.not. allocated(self%band_pairs)) allocate (self%band_pairs(2, 16))
    call self%sleep%update(bodies, shapes, flight, h, self%band_pairs, self%n_band_pairs)
  end subroutine stage_settle

  !> The step ends before this rank's earliest contact (another rank's came first): no pair
  !> of this rank is in contact at its end.
  module subroutine stage_drop_events(self)
    class(collision_stage_t), intent(inout) :: self
    self%n_events = 0
  end subroutine stage_drop_events

  !> Every sleeping body wakes (checkpoints: a restart continues exactly).
  module subroutine stage_wake_all(self, bodies, flight)
    class(collision_stage_t), intent(inout) :: self
    type(bodies_t), intent(inout) :: bodies
    type(free_flight_t), intent(inout) :: flight
    call self%sleep%wake_all(bodies, flight)
  end subroutine stage_wake_all

end submodule collision_stage_impacts
