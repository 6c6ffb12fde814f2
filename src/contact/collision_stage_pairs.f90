!> Set-up of the collision stage and the step's candidate pairs: tolerances and the grid box
!> from the deck (init), the step limit that keeps every body within one grid box
!> (limit_step), the candidate pairs with their gaps at the step's start (prepare), and room
!> in the pair table for the pairs the local event loop enters itself (reserve_table).
!> A submodule rather than a module of its own: it fills the stage's pair table, which
!> stays private to collision_stage.
submodule (collision_stage) collision_stage_pairs
  use error_status, only: ERR_INPUT
  use string_utils, only: str
  use bucket_grid, only: choose_box_size
  use pair_geometry, only: pair_gap, gap_lower_bound, bounding_sphere_boxes
  implicit none

contains

  module subroutine stage_init(self, contact, run, materials, source, shapes, bodies, err, smallest_extent)
    class(collision_stage_t), intent(inout) :: self
    type(contact_config_t), intent(in) :: contact
    type(run_config_t), intent(in) :: run
    type(material_table_t), intent(in) :: materials
    character(len=*), intent(in) :: source
    type(shape_library_t), intent(in) :: shapes
    type(bodies_t), intent(in) :: bodies
    type(error_t), intent(inout) :: err
    real(dp), intent(in), optional :: smallest_extent
    real(dp) :: smallest
    if (present(smallest_extent)) then
      smallest = smallest_extent
    else
      smallest = smallest_moving_extent(shapes, bodies)
    end if
    self%target = min_separation_for(contact, smallest)
    call self%memo%clear()
    if (smallest >= huge(1.0_dp)) smallest = 1.0_dp   ! nothing moves: any box will do
    ! The advancement stops within 10% of the minimum separation above it; contact points
    ! are all features within one minimum separation of the closest one.
    self%tolerance = 0.1_dp*self%target
    self%contact_tolerance = self%target
    self%velocity_tolerance = 1.0e-9_dp
    ! Below this approach speed an impact is inelastic (docs/contact.md, "Resting contact"):
    ! the speed gravity adds in two steps, or the speed of a fall through the separation.
    if (contact%rest_speed >= 0.0_dp) then
      self%rest_speed = contact%rest_speed
    else
      self%rest_speed = max(2.0_dp*norm2(run%gravity)*run%dt_max, &
                            sqrt(2.0_dp*norm2(run%gravity)*self%target))
    end if
    self%materials = materials
    ! Sleeping (docs/contact.md): auto speed 1% of the rest speed, so off without gravity.
    if (contact%sleep_speed >= 0.0_dp) then
      call self%sleep%init(bodies%n_owned + bodies%n_ghost, contact%sleep_speed, contact%sleep_time)
    else
      call self%sleep%init(bodies%n_owned + bodies%n_ghost, 1.0e-2_dp*self%rest_speed, contact%sleep_time)
    end if
    self%settle_speed = max(self%velocity_tolerance, 1.0e-3_dp*self%rest_speed)
    self%resting%velocity_tolerance = self%velocity_tolerance
    self%resting%turning_slack = 0.25_dp*self%target
    self%turning_term = contact%turning_term
    call choose_box_size([smallest], 1.0_dp, self%box_size, err)
    if (err%failed()) return
    ! Each step keeps every body's travel plus the contact band within one grid box
    ! (limit_step): a band of half a box or more leaves no room to move.
    if (self%target + self%tolerance >= 0.5_dp*self%box_size) then
      call err%set(ERR_INPUT, source//': &contact: min_separation = '//str(self%target, '(es10.3)')// &
                   ' m is too large for the smallest moving body (extent '//str(smallest, '(es10.3)')// &
                   ' m): it must stay below '//str(0.5_dp*self%box_size/1.1_dp, '(es10.3)')// &
                   ' m, and well below that for accurate contact')
      return
    end if
    call self%grid%init(self%box_size, err)
  end subroutine stage_init

  !> The largest step that keeps every body within one grid box: |v| h + |a| h^2 + band <= box
  !> (a: gravity, or the acceleration of a loaded body, zero; the parabola needs |a| h^2/2, the
  !> motion at v + g h the contact pass may give |a| h^2; band: the contact band).
  !> members, when present: only these bodies (an island of the local loop).
  module pure real(dp) function stage_limit_step(self, bodies, flight, gravity, h, members) result(limited)
    class(collision_stage_t), intent(in) :: self
    type(bodies_t), intent(in) :: bodies
    type(free_flight_t), intent(in) :: flight
    real(dp), intent(in) :: gravity(3), h
    integer, intent(in), optional :: members(:)
    real(dp) :: room
    integer :: i, m
    limited = h
    ! Each body enters the grid with its travel bound |v| h + |a| h^2 (prepare) plus the
    ! contact band: that sum stays within one box, so two rings find every pair.
    room = self%box_size - (self%target + self%tolerance)
    if (present(members)) then
      do m = 1, size(members)
        call limit_one(members(m))
      end do
    else
      do i = 1, bodies%n_owned
        call limit_one(i)
      end do
    end if
  contains
    pure subroutine limit_one(k)
      integer, intent(in) :: k
      real(dp) :: speed, g
      if (bodies%fixed(k)) return
      g = norm2(flight%acceleration(k, gravity))
      speed = norm2(bodies%v(:, k))
      if (speed*limited + g*limited*limited > room) &
        limited = 2.0_dp*room/(speed + sqrt(speed*speed + 4.0_dp*g*room))
    end subroutine limit_one
  end function stage_limit_step

  !> The step's candidate pairs, once per step before the contact pass. Every moving body
  !> enters the grid with its travel bound over the step h as margin, |v| h + |a| h^2: the
  !> parabola needs |a| h^2/2, the motion at v + g h that the contact pass gives a loaded
  !> body |a| h^2 (translation only: the bounding sphere does not grow when a body turns).
  !> Pairs that cannot come within the contact band in the step are far; the others get
  !> their gap and normal at the step's start, which the contact pass and the time of
  !> contact share (the pass changes velocities, not positions).
  !> margins, when present: the travel bounds to enter the bodies with instead (the pass
  !> made a body faster than its margin allowed); gaps already known are kept.
  module subroutine stage_prepare(self, bodies, shapes, flight, h, gravity, err, margins)
    class(collision_stage_t), intent(inout) :: self
    type(bodies_t), intent(in) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(in) :: flight
    real(dp), intent(in) :: h, gravity(3)
    type(error_t), intent(inout) :: err
    real(dp), intent(in), optional :: margins(:)
    real(dp), allocatable :: lower(:, :), upper(:, :), old_gap(:), old_normal(:, :)
    integer, allocatable :: old_pairs(:, :)
    logical, allocatable :: old_far(:), old_in_pass(:)
    integer :: n, i, j, k, n_old, slot
    real(dp) :: reach

    n = bodies%n_owned + bodies%n_ghost
    n_old = 0
    if (present(margins)) then
      n_old = self%n_pairs
      old_pairs = self%pairs(:, 1:n_old)
      old_gap = self%pair_gap0(1:n_old)
      old_normal = self%pair_normal(:, 1:n_old)
      old_far = self%pair_far(1:n_old)
      old_in_pass = self%pair_in_pass(1:n_old)
    end if
    self%n_pairs = 0
    if (n < 2) return
    if (allocated(self%grid_margin)) then
      if (size(self%grid_margin) < n) deallocate (self%grid_margin, self%turn)
    end if
    if (.not. allocated(self%grid_margin)) allocate (self%grid_margin(n), self%turn(n))
    do i = 1, n
      self%turn(i) = turning_reach(shapes, bodies, i)*h
      if (bodies%fixed(i)) then
        self%grid_margin(i) = 0.0_dp
      else if (present(margins)) then
        self%grid_margin(i) = margins(i)
      else
        self%grid_margin(i) = norm2(bodies%v(:, i))*h + norm2(flight%acceleration(i, gravity))*h*h
      end if
    end do
    allocate (lower(3, n), upper(3, n))
    call bounding_sphere_boxes(shapes, bodies, n, lower, upper)
    call self%grid%build(n, lower, upper, bodies%fixed(1:n), err)
    if (err%failed()) return
    ! Boxes inflated by the travel and the band each: a pair whose boxes stay apart cannot come
    ! within twice the band in the step (without the band, two balls 0.35 mm apart and
    ! closing slower than that per step were never listed, and rolled below the floor).
    call self%grid%candidate_pairs(2, self%grid_margin(1:n) + (self%target + self%tolerance), self%pairs, &
                                   self%n_pairs, err, n_owned=bodies%n_owned)
    if (err%failed()) return
    if (allocated(self%pair_gap0)) then
      if (size(self%pair_gap0) < self%n_pairs) deallocate (self%pair_gap0, self%pair_normal, self%pair_far, &
                                                            self%pair_in_pass)
    end if
    if (.not. allocated(self%pair_gap0)) allocate (self%pair_gap0(max(self%n_pairs, 16)), &
      self%pair_normal(3, max(self%n_pairs, 16)), self%pair_far(max(self%n_pairs, 16)), &
      self%pair_in_pass(max(self%n_pairs, 16)))
    slot = 1
    do k = 1, self%n_pairs
      i = self%pairs(1, k)
      j = self%pairs(2, k)
      self%pair_in_pass(k) = .false.
      ! Both lists are sorted by (first, second): walk the old one alongside.
      do while (slot <= n_old)
        if (old_pairs(1, slot) > i .or. (old_pairs(1, slot) == i .and. old_pairs(2, slot) >= j)) exit
        slot = slot + 1
      end do
      if (slot <= n_old) then
        if (old_pairs(1, slot) == i .and. old_pairs(2, slot) == j .and. .not. old_far(slot)) then
          self%pair_gap0(k) = old_gap(slot)
          self%pair_normal(:, k) = old_normal(:, slot)
          self%pair_far(k) = .false.
          self%pair_in_pass(k) = old_in_pass(slot)
          cycle
        end if
      end if
      self%pair_gap0(k) = huge(1.0_dp)
      self%pair_far(k) = .true.
      if (bodies%fixed(i) .and. bodies%fixed(j)) cycle
      ! Bounding spheres and boxes first: a pair that cannot come within the contact band in
      ! this step costs no closest-point query.
      reach = self%grid_margin(i) + self%grid_margin(j)
      self%pair_gap0(k) = gap_lower_bound(shapes, bodies, i, j, reach + 2.0_dp*(self%target + self%tolerance), &
                                          self%turn(i), self%turn(j))
      if (self%pair_gap0(k) - reach > 2.0_dp*(self%target + self%tolerance)) cycle
      self%pair_far(k) = .false.
      call pair_gap(shapes, bodies, i, j, bodies%x(:, i), bodies%q(:, i), bodies%x(:, j), bodies%q(:, j), &
                    self%pair_gap0(k), self%pair_normal(:, k))
      self%stats%pair_tests = self%stats%pair_tests + 1
      self%stats%min_separation = min(self%stats%min_separation, self%pair_gap0(k))
    end do
  end subroutine stage_prepare

  !> Room in the step's pair table for m pairs of n bodies (the local event loop fills the
  !> table with an island's pairs, or one pair, itself).
  module subroutine stage_reserve_table(self, m, n)
    class(collision_stage_t), intent(inout) :: self
    integer, intent(in) :: m, n
    integer :: c
    c = max(m, 16)
    if (allocated(self%pair_gap0)) then
      if (size(self%pair_gap0) < m) deallocate (self%pair_gap0, self%pair_normal, self%pair_far, self%pair_in_pass)
    end if
    if (.not. allocated(self%pair_gap0)) allocate (self%pair_gap0(c), self%pair_normal(3, c), self%pair_far(c), &
                                                   self%pair_in_pass(c))
    if (allocated(self%pairs)) then
      if (size(self%pairs, 2) < m) deallocate (self%pairs)
    end if
    if (.not. allocated(self%pairs)) allocate (self%pairs(2, c))
    if (allocated(self%grid_margin)) then
      if (size(self%grid_margin) < n) deallocate (self%grid_margin, self%turn)
    end if
    if (.not. allocated(self%grid_margin)) then
      allocate (self%grid_margin(n), self%turn(n))
      self%grid_margin = 0.0_dp
      self%turn = 0.0_dp
    end if
  end subroutine stage_reserve_table

  module subroutine stage_remap_bodies(self, new_index, n)
    class(collision_stage_t), intent(inout) :: self
    integer, intent(in) :: new_index(:)
    integer, intent(in) :: n
    call self%sleep%remap_bodies(new_index, n)
    call self%resting%remap_bodies(new_index, n)
    ! (travel bounds and turning of the step being set up: written before each use)
    if (allocated(self%grid_margin)) deallocate (self%grid_margin, self%turn)
    call self%reserve_table(16, n)
  end subroutine stage_remap_bodies

end submodule collision_stage_pairs
