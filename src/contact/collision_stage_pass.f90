!> The contact pass at the start of a step (resting_contact): the persistent and speculative
!> contacts of the step's candidate pairs, with the sleeping islands they reach woken, solved
!> at velocity level (contact_pass); the pairs it found in the band, which sleeping looks at
!> (record_band_pairs); and, when the step is cut, the part of the pass's velocity change for
!> the time not taken given back (return_unused_pass). A submodule: it reads the stage's pair
!> table and marks the pairs it solved there.
submodule (collision_stage) collision_stage_pass
  use impulse_solver, only: normal_velocity, normal_curvature
  use pair_geometry, only: pair_contact_points
  implicit none

contains

  !> The contact pass at the start of a step of h [s] (resting_contact), over the step's
  !> candidate pairs (prepare):
  !>  - contact points of pairs within the contact band (gap up to target + tolerance +
  !>    contact tolerance) that do not separate faster than gravity can close in the step
  !>    are persistent: for inelastic pairs (e = 0) at any approach speed (an inelastic impact
  !>    is what the pass does), for others only up to the rest speed (faster ones are
  !>    impacts, left to the event with their restitution);
  !>  - inelastic pairs further apart that can reach the band within the step get
  !>    speculative contact points: they may approach at up to the speed that closes their
  !>    gap to the target in the step (contact_t%allowed_approach), and join the solve when
  !>    they would approach faster (they would touch within the step). A landing is then
  !>    solved with the step instead of cutting it at the time of contact; conservative
  !>    advancement still checks the motion (the pair may come down to the settling floor).
  !> Solved with e = 0 and friction; sets the loads the propagator applies over the step.
  !> members, when present: the island of the local event loop this pass is for (its pairs
  !> are the step's pairs, its sleeping neighbours already woken by the caller); those of
  !> them in no persistent contact fly free. Default: the whole scene (the global loop).
  module subroutine stage_contact_pass(self, bodies, shapes, flight, h, gravity, err, members)
    class(collision_stage_t), intent(inout) :: self
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    real(dp), intent(in) :: h, gravity(3)
    type(error_t), intent(inout) :: err
    integer, intent(in), optional :: members(:)
    logical, allocatable :: persistent(:)
    real(dp), allocatable :: u_start(:)
    integer :: n, i, n_contacts, c, kept, round
    real(dp) :: separating_limit
    logical :: grew, woke
    n = bodies%n_owned + bodies%n_ghost
    n_contacts = 0
    self%pass_step = h
    self%n_band_pairs = 0
    call ensure_held(self, n)
    if (n >= 2 .and. h > 0.0_dp) then
      ! Each round wakes at least one island: at most as many rounds as islands asleep.
      do round = 1, n + 1
        call pass_contacts(self, bodies, shapes, h, n_contacts)
        if (present(members)) exit
        call wake_reached(self, bodies, flight, h, gravity, n_contacts, woke)
        if (.not. woke) exit
        ! the woken bodies' pairs with each other were static-static pairs, never listed
        call self%prepare(bodies, shapes, flight, h, gravity, err)
        if (err%failed()) return
      end do
      call record_band_pairs(self, n_contacts)
    end if
    kept = 0
    if (n_contacts > 0) then
      allocate (persistent(n_contacts))
      ! Contacts separating faster than gravity can close in the step need no impulse; leaving
      ! them out keeps a body that bounces off the floor on its exact parabola.
      separating_limit = 2.0_dp*norm2(gravity)*h + self%velocity_tolerance
      allocate (u_start(n_contacts))
      do c = 1, n_contacts
        u_start(c) = normal_velocity(bodies, self%contacts(c))
        if (self%contacts(c)%speculative) then
          persistent(c) = speculative_active(c)
        else if (self%contacts(c)%restitution <= 0.0_dp) then
          persistent(c) = u_start(c) <= separating_limit .or. speculative_active(c)
        else
          persistent(c) = u_start(c) >= -self%rest_speed .and. u_start(c) <= separating_limit
        end if
        if (persistent(c)) call hold(c)
      end do
      ! ... but a body the pass will push keeps all its contacts in the band (and its
      ! speculative ones) as constraints, or the push could turn a separating contact of it
      ! into an approaching one. That holds the body at the contact's other end too, so this
      ! runs to a fixed point: with one sweep, a chain held -> held -> spinning body left the
      ! last body's separating contact out, the pass turned it into an approaching one, the
      ! event at time 0 took the pass back, and the run stalled (27-cube pile).
      do
        grew = .false.
        do c = 1, n_contacts
          if (persistent(c)) cycle
          if (.not. (self%held(self%contacts(c)%a) .or. self%held(self%contacts(c)%b))) cycle
          if (self%contacts(c)%restitution > 0.0_dp .and. u_start(c) < -self%rest_speed) cycle
          persistent(c) = .true.
          call hold(c)
          grew = .true.
        end do
        if (.not. grew) exit
      end do
      kept = count(persistent)
      do c = 1, n_contacts
        if (persistent(c)) self%pair_in_pass(self%contact_pair(c)) = .true.
        self%held(self%contacts(c)%a) = .false.
        self%held(self%contacts(c)%b) = .false.
      end do
      if (kept < n_contacts) then
        self%contacts(1:kept) = pack(self%contacts(1:n_contacts), persistent)
        self%keys(:, 1:kept) = self%keys(:, pack([(c, c=1, n_contacts)], persistent))
      end if
    end if
    if (kept > 0 .and. h > 0.0_dp) then
      call self%resting%solve(bodies, flight, self%contacts(1:kept), self%keys(:, 1:kept), kept, h, gravity, err, &
                              members)
    else if (present(members)) then
      do i = 1, size(members)
        if (members(i) <= bodies%n_owned) call flight%clear_load(members(i))
      end do
    else
      do i = 1, bodies%n_owned
        call flight%clear_load(i)
      end do
    end if
  contains

    subroutine hold(cc)
      integer, intent(in) :: cc
      self%held(self%contacts(cc)%a) = .not. bodies%fixed(self%contacts(cc)%a)
      self%held(self%contacts(cc)%b) = .not. bodies%fixed(self%contacts(cc)%b)
    end subroutine hold

    !> A speculative contact joins on its own when, with gravity's impulse for the step, it
    !> would approach faster than it may: the pair would touch within the step.
    logical function speculative_active(cc)
      integer, intent(in) :: cc
      speculative_active = u_start(cc) + gravity_closing(bodies, self%contacts(cc), gravity, h) < &
                           -self%contacts(cc)%allowed_approach
    end function speculative_active

  end subroutine stage_contact_pass

  !> The pass's per-body flags, all false between passes (set and cleared for its contacts'
  !> bodies only: a pass costs its contacts, not the scene).
  subroutine ensure_held(self, n)
    type(collision_stage_t), intent(inout) :: self
    integer, intent(in) :: n
    if (allocated(self%held)) then
      if (size(self%held) >= n) return
      deallocate (self%held)
    end if
    allocate (self%held(n))
    self%held = .false.
  end subroutine ensure_held

  !> Change of a contact's normal velocity from gravity's impulse over h for the moving bodies
  !> (zero when both move: gravity does not change their relative velocity) [m/s].
  pure real(dp) function gravity_closing(bodies, c, gravity, h)
    type(bodies_t), intent(in) :: bodies
    type(contact_t), intent(in) :: c
    real(dp), intent(in) :: gravity(3), h
    gravity_closing = 0.0_dp
    if (.not. bodies%fixed(c%b)) gravity_closing = gravity_closing + dot_product(c%normal, gravity)*h
    if (.not. bodies%fixed(c%a)) gravity_closing = gravity_closing - dot_product(c%normal, gravity)*h
  end function gravity_closing

  !> The contact pass's contact points, from the step's candidate pairs (prepare) into
  !> self%contacts(1:n_contacts), with their keys and candidate pairs: every pair within the
  !> contact band, and the inelastic pairs that can reach it within the step h as
  !> speculative contacts (allowed_approach: the speed that closes each contact point's own
  !> feature gap to target + tolerance in the step).
  subroutine pass_contacts(self, bodies, shapes, h, n_contacts)
    type(collision_stage_t), intent(inout) :: self
    type(bodies_t), intent(in) :: bodies
    type(shape_library_t), intent(in) :: shapes
    real(dp), intent(in) :: h
    integer, intent(out) :: n_contacts
    integer :: k, i, j, first, c
    real(dp) :: gap, band, aim, restitution, reach
    integer, allocatable :: grown(:)
    n_contacts = 0
    band = self%target + self%tolerance + self%contact_tolerance
    aim = self%target + self%tolerance
    do k = 1, self%n_pairs
      if (self%pair_far(k)) cycle
      i = self%pairs(1, k)
      j = self%pairs(2, k)
      if (bodies%fixed(i) .and. bodies%fixed(j)) cycle
      gap = self%pair_gap0(k)
      restitution = self%materials%pair_restitution(bodies%group_id(i), bodies%group_id(j))
      ! how far the pair can close in the step (translation and turning)
      reach = self%grid_margin(i) + self%grid_margin(j) + self%turn(i) + self%turn(j)
      if (gap > band) then
        if (restitution > 0.0_dp) cycle
        if (gap - band > reach) cycle
      end if
      first = n_contacts + 1
      if (restitution > 0.0_dp) then
        call pair_contact_points(shapes, bodies, i, j, gap, self%pair_normal(:, k), self%contact_tolerance, &
                                 self%contacts, self%keys, n_contacts, self%features)
      else
        ! every feature pair that can touch within the step (another edge of a tumbling body
        ! coming down), each allowed to close to the target and no further
        call pair_contact_points(shapes, bodies, i, j, gap, self%pair_normal(:, k), self%contact_tolerance, &
                                 self%contacts, self%keys, n_contacts, self%features, search=min(reach, band + reach - gap))
      end if
      self%contacts(first:n_contacts)%restitution = restitution
      self%contacts(first:n_contacts)%friction = self%materials%pair_friction(bodies%group_id(i), bodies%group_id(j))
      ! inelastic pairs: every contact point may close to the band (target + tolerance) in the
      ! step and no further; elastic ones (slow, in the band) may not approach at all
      if (restitution <= 0.0_dp) then
        do c = first, n_contacts
          self%contacts(c)%speculative = self%contacts(c)%gap > aim
          ! less what turning brings the contact closer than the straight line by the step's
          ! end (a sliding or turning pair curves into the band's floor otherwise); negative:
          ! the contact must open at that speed
          self%contacts(c)%turning = self%turning_term
          self%contacts(c)%allowed_straight = max(self%contacts(c)%gap - aim, 0.0_dp)/h
          self%contacts(c)%allowed_approach = self%contacts(c)%allowed_straight
          if (self%turning_term) self%contacts(c)%allowed_approach = self%contacts(c)%allowed_approach - &
                                              0.5_dp*h*max(-normal_curvature(bodies, self%contacts(c)), 0.0_dp)
        end do
      end if
      if (.not. allocated(self%contact_pair)) allocate (self%contact_pair(max(64, size(self%contacts))))
      if (size(self%contact_pair) < n_contacts) then
        allocate (grown(2*n_contacts))
        grown(1:first - 1) = self%contact_pair(1:first - 1)
        call move_alloc(grown, self%contact_pair)
      end if
      self%contact_pair(first:n_contacts) = k
    end do
  end subroutine pass_contacts

  !> Sleeping islands that a moving body reaches wake: contacts in the band, and speculative
  !> ones that would touch within the step (the impact is then solved with the island's
  !> real masses, not against a support that cannot give way).
  subroutine wake_reached(self, bodies, flight, h, gravity, n_contacts, woke)
    type(collision_stage_t), intent(inout) :: self
    type(bodies_t), intent(inout) :: bodies
    type(free_flight_t), intent(inout) :: flight
    real(dp), intent(in) :: h, gravity(3)
    integer, intent(in) :: n_contacts
    logical, intent(out) :: woke
    logical, allocatable :: reached(:)
    integer :: c
    woke = .false.
    if (self%sleep%n_asleep == 0 .or. n_contacts == 0) return
    allocate (reached(n_contacts))
    do c = 1, n_contacts
      associate (con => self%contacts(c))
        reached(c) = .not. con%speculative
        if (.not. reached(c)) reached(c) = normal_velocity(bodies, con) + gravity_closing(bodies, con, gravity, h) < &
                                           -con%allowed_approach
      end associate
    end do
    call self%sleep%wake_touching(bodies, flight, pack(self%contacts(1:n_contacts), reached), woke)
  end subroutine wake_reached

  !> The distinct body pairs of self%contacts(1:n_contacts): the islands sleeping looks at.
  subroutine record_band_pairs(self, n_contacts)
    type(collision_stage_t), intent(inout) :: self
    integer, intent(in) :: n_contacts
    integer :: c
    if (.not. allocated(self%band_pairs)) allocate (self%band_pairs(2, max(n_contacts, 16)))
    if (size(self%band_pairs, 2) < n_contacts) then
      deallocate (self%band_pairs)
      allocate (self%band_pairs(2, 2*n_contacts))
    end if
    self%n_band_pairs = 0
    do c = 1, n_contacts
      if (self%contacts(c)%speculative) cycle   ! not touching
      ! contact points of one pair are consecutive: keep the first of each run
      if (self%n_band_pairs > 0) then
        if (self%band_pairs(1, self%n_band_pairs) == self%contacts(c)%a .and. &
            self%band_pairs(2, self%n_band_pairs) == self%contacts(c)%b) cycle
      end if
      self%n_band_pairs = self%n_band_pairs + 1
      self%band_pairs(:, self%n_band_pairs) = [self%contacts(c)%a, self%contacts(c)%b]
    end do
  end subroutine record_band_pairs

  !> The contact pass gave the bodies it pushed the velocity change of the whole planned
  !> step (gravity's impulse and the contact impulses that answer it); when an event (or the
  !> grid) cut the step short, the part for the time not taken is taken back: the velocity
  !> becomes v_start + (h_taken/h) dv, so cut steps do not pump energy in. That is a convex
  !> combination of the start velocity and the solved one, so a persistent contact that
  !> approached at neither does not approach now. The motion over the step was the one
  !> conservative advancement checked; only the velocities change.
  !> members and pass_step, when present: an island of the local loop, whose own pass was
  !> for a step of pass_step [s] (default: every owned body, the last pass's step).
  module subroutine stage_return_unused_pass(self, bodies, flight, h_taken, members, pass_step)
    class(collision_stage_t), intent(in) :: self
    type(bodies_t), intent(inout) :: bodies
    type(free_flight_t), intent(inout) :: flight
    real(dp), intent(in) :: h_taken   !< the step taken [s]
    integer, intent(in), optional :: members(:)
    real(dp), intent(in), optional :: pass_step
    real(dp) :: unused, planned
    integer :: i, m
    planned = self%pass_step
    if (present(pass_step)) planned = pass_step
    if (h_taken >= planned) return
    unused = 1.0_dp - h_taken/planned
    if (present(members)) then
      do m = 1, size(members)
        call take_back(members(m))
      end do
    else
      do i = 1, bodies%n_owned
        call take_back(i)
      end do
    end if
  contains
    subroutine take_back(k)
      integer, intent(in) :: k
      if (k > bodies%n_owned) return
      if (bodies%fixed(k) .or. .not. flight%loaded(k)) return
      bodies%v(:, k) = bodies%v(:, k) - unused*self%resting%dv(:, k)
      bodies%w(:, k) = bodies%w(:, k) - unused*self%resting%dw(:, k)
      call flight%release(k)
    end subroutine take_back
  end subroutine stage_return_unused_pass

end submodule collision_stage_pass
