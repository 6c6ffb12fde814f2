!> The distance correction of the step's candidate pairs (correct_distances): pairs settled
!> below three quarters of the minimum separation are opened by the smallest mass-weighted
!> moves that keep the other candidate pairs as far apart, positions only.
!> A submodule: it works on the stage's pair table and its local numbering of bodies
!> (slot_of), both private to collision_stage.
submodule (collision_stage) collision_stage_correction
  use pair_geometry, only: pair_gap
  implicit none

contains

  !> Distance correction of the step's candidate pairs (after prepare): pairs that have
  !> settled below three quarters of the minimum separation (turning bodies in contact come
  !> down towards the floor, and a contact solve leaves residuals) are opened to the target
  !> plus half the tolerance by moving bodies, positions only (velocities, and so kinetic
  !> energy, stay), by the smallest mass-weighted translations that also keep every other
  !> candidate pair at least as far apart as it was or at that target, whichever is less:
  !>     min sum_i m_i |d_i|^2   subject to   g_k + n_k.(d_b - d_a) >= min(g_k, aim) for all k,
  !>                                          g_k + n_k.(d_b - d_a) >= aim for the low pairs,
  !> solved by projected Gauss-Seidel over the constraint multipliers (a body in a stack pushes
  !> the ones above it too, instead of being refused as one pair at a time was). For convex
  !> pairs g + n.(d_b - d_a) is a lower bound on the new gap (the projections on n move apart
  !> by that much), so the result holds by construction; every pair of a moved body is then
  !> measured again, and if one still came closer than allowed (a non-convex pair, or
  !> an unconverged solve) the move is halved, up to four times, or not made.
  !> No body moves more than half the band, (target + tolerance)/2, in one step: pairs
  !> that prepare found far (or never listed) were at least that much beyond reach, so
  !> they stay out of the band (one low pair never needs more, since gaps stay above
  !> target/2; a chain of low pairs opens over several steps).
  module subroutine stage_correct_distances(self, bodies, shapes, flight)
    class(collision_stage_t), intent(inout) :: self
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    !> Gaps below this fraction of the target are corrected.
    real(dp), parameter :: trigger = 0.75_dp
    integer, parameter :: max_sweeps = 200, max_halvings = 4
    real(dp), allocatable :: lam(:), bound(:), d(:, :), x_saved(:, :), gap_new(:), normal_new(:, :)
    logical, allocatable :: active(:), moves(:)
    integer, allocatable :: local(:, :), body_of(:)
    integer :: n, k, i, j, sweep, halving, nb, li, lj, b
    real(dp) :: aim, weight, residual, dl, worst, alpha, largest
    logical :: ok
    n = bodies%n_owned + bodies%n_ghost
    if (self%n_pairs == 0) return
    if (.not. any(.not. self%pair_far(1:self%n_pairs) .and. self%pair_gap0(1:self%n_pairs) < trigger*self%target)) return
    aim = self%target + 0.5_dp*self%tolerance
    allocate (lam(self%n_pairs), bound(self%n_pairs), active(self%n_pairs), local(2, self%n_pairs))
    ! The constraints: every near pair with a moving body.
    lam = 0.0_dp
    do k = 1, self%n_pairs
      i = self%pairs(1, k)
      j = self%pairs(2, k)
      active(k) = .not. self%pair_far(k) .and. .not. (bodies%fixed(i) .and. bodies%fixed(j))
      if (.not. active(k)) cycle
      bound(k) = min(self%pair_gap0(k), aim)
      if (self%pair_gap0(k) < trigger*self%target) bound(k) = aim
    end do
    ! The bodies of the constraints, numbered locally (a correction costs its pairs, not the
    ! scene): body_of(1:nb), local(:, k) the local numbers of pair k's bodies.
    call number_pair_bodies(self, n, active, local, body_of, nb)
    allocate (d(3, nb), moves(nb))
    d = 0.0_dp
    do sweep = 1, max_sweeps
      worst = 0.0_dp
      do k = 1, self%n_pairs
        if (.not. active(k)) cycle
        i = self%pairs(1, k)
        j = self%pairs(2, k)
        li = local(1, k)
        lj = local(2, k)
        weight = bodies%inv_mass(i) + bodies%inv_mass(j)
        if (weight <= 0.0_dp) cycle
        residual = self%pair_gap0(k) + dot_product(self%pair_normal(:, k), d(:, lj) - d(:, li)) - bound(k)
        dl = max(-residual/weight, -lam(k))
        if (dl == 0.0_dp) cycle
        lam(k) = lam(k) + dl
        d(:, lj) = d(:, lj) + bodies%inv_mass(j)*dl*self%pair_normal(:, k)
        d(:, li) = d(:, li) - bodies%inv_mass(i)*dl*self%pair_normal(:, k)
        worst = max(worst, abs(residual))
      end do
      if (worst <= 1.0e-3_dp*self%target) exit
    end do
    do b = 1, nb
      moves(b) = any(d(:, b) /= 0.0_dp) .and. .not. bodies%fixed(body_of(b))
    end do
    if (.not. any(moves)) return
    allocate (x_saved(3, nb))
    do b = 1, nb
      x_saved(:, b) = bodies%x(:, body_of(b))
    end do
    allocate (gap_new(self%n_pairs), normal_new(3, self%n_pairs))
    largest = maxval(norm2(d, dim=1), mask=moves)
    alpha = min(1.0_dp, 0.5_dp*(self%target + self%tolerance)/largest)
    if (alpha < 1.0_dp) self%stats%corrections_capped = self%stats%corrections_capped + 1
    do halving = 0, max_halvings
      do b = 1, nb
        if (moves(b)) bodies%x(:, body_of(b)) = x_saved(:, b) + alpha*d(:, b)
      end do
      ! Measure every pair of a moved body: none may end closer than its bound allows
      ! (the low ones at least no closer than they were).
      ok = .true.
      do k = 1, self%n_pairs
        if (.not. active(k)) cycle
        i = self%pairs(1, k)
        j = self%pairs(2, k)
        if (.not. (moved(i) .or. moved(j))) cycle
        call pair_gap(shapes, bodies, i, j, bodies%x(:, i), bodies%q(:, i), bodies%x(:, j), bodies%q(:, j), &
                      gap_new(k), normal_new(:, k))
        self%stats%pair_tests = self%stats%pair_tests + 1
        ! (never below the floor target/2, which the gap was above)
        if (gap_new(k) < max(min(self%pair_gap0(k), bound(k)) - 1.0e-3_dp*self%target, &
                             min(self%pair_gap0(k), 0.5_dp*self%target))) then
          ok = .false.
          exit
        end if
      end do
      if (ok) exit
      alpha = 0.5_dp*alpha
    end do
    if (.not. ok) then
      do b = 1, nb
        bodies%x(:, body_of(b)) = x_saved(:, b)
      end do
      call clear_numbers()
      return
    end if
    do k = 1, self%n_pairs
      i = self%pairs(1, k)
      j = self%pairs(2, k)
      if (.not. (moved(i) .or. moved(j))) cycle
      if (active(k)) then
        self%pair_gap0(k) = gap_new(k)
        self%pair_normal(:, k) = normal_new(:, k)
      else if (self%pair_far(k) .and. .not. (bodies%fixed(i) .and. bodies%fixed(j))) then
        ! a far pair of a moved body is far no more: measured, to keep prepare's promise
        self%pair_far(k) = .false.
        call pair_gap(shapes, bodies, i, j, bodies%x(:, i), bodies%q(:, i), bodies%x(:, j), bodies%q(:, j), &
                      self%pair_gap0(k), self%pair_normal(:, k))
        self%stats%pair_tests = self%stats%pair_tests + 1
      end if
      self%stats%min_separation = min(self%stats%min_separation, self%pair_gap0(k))
    end do
    do b = 1, nb
      if (moves(b)) call flight%release(body_of(b))
    end do
    self%stats%corrections = self%stats%corrections + count(moves)
    call clear_numbers()
  contains
    logical function moved(body)
      integer, intent(in) :: body
      moved = .false.
      if (self%slot_of(body) > 0) moved = moves(self%slot_of(body))
    end function moved
    subroutine clear_numbers()
      integer :: bb
      do bb = 1, nb
        self%slot_of(body_of(bb)) = 0
      end do
    end subroutine clear_numbers
  end subroutine stage_correct_distances

  !> Local numbers 1..nb for the bodies of the active pairs, in order of first appearance
  !> (body_of(1:nb)); local(:, k): those of pair k's bodies. self%slot_of holds the numbers
  !> until the caller clears them (it is all zero between calls).
  subroutine number_pair_bodies(self, n, active, local, body_of, nb)
    type(collision_stage_t), intent(inout) :: self
    integer, intent(in) :: n
    logical, intent(in) :: active(:)
    integer, intent(out) :: local(:, :)
    integer, allocatable, intent(out) :: body_of(:)
    integer, intent(out) :: nb
    integer :: k, c, body
    if (allocated(self%slot_of)) then
      if (size(self%slot_of) < n) deallocate (self%slot_of)
    end if
    if (.not. allocated(self%slot_of)) then
      allocate (self%slot_of(n))
      self%slot_of = 0
    end if
    allocate (body_of(2*count(active)))
    nb = 0
    local = 0
    do k = 1, size(active)
      if (.not. active(k)) cycle
      do c = 1, 2
        body = self%pairs(c, k)
        if (self%slot_of(body) == 0) then
          nb = nb + 1
          body_of(nb) = body
          self%slot_of(body) = nb
        end if
        local(c, k) = self%slot_of(body)
      end do
    end do
  end subroutine number_pair_bodies

end submodule collision_stage_correction
