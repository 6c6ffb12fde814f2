!> Whether a run on several ranks may split its bodies (docs/architecture.md, "Domain
!> decomposition"): until cross-rank contacts are built, ranks that own bricks of the scene
!> find contacts among their own bodies alone, which is exact only when no two bodies can
!> ever interact. So a run on several ranks first asks whether any interaction is possible
!> at all before t_end: without one, every body flies free and the bricks are exact; with
!> one, every body is given to rank 0, which then runs the scene exactly as one rank does
!> (the other ranks take part in the collectives with no bodies), never a silently wrong
!> answer.
module ownership
  use kinds, only: dp, i8
  use shape, only: shape_library_t
  use body_state, only: bodies_t
  use sorting, only: sort_index_real
  use parallel_env, only: parallel_t
  implicit none
  private
  public :: contact_possible

contains

  !> Whether any two bodies (not both fixed) can come into contact between t0 and t_end
  !> if every free body flies free: each body's centre follows x + v t + g t^2/2, so its
  !> bounding sphere stays within the box of that parabola arc inflated by the radius;
  !> boxes that never overlap are bodies that never touch (rotation does not move the
  !> centre). Should no pair's boxes overlap, no contact ever changes a trajectory, so
  !> the free flights are the run. Sort and sweep along x: O(n log n) plus the overlaps.
  !> bodies holds every body of the run, on every rank.
  !> margin: a gap below which two bodies interact without touching (the contact band of
  !> the minimum separation: distance corrections and contact passes act there) [m].
  !>
  !> The sweep is the costly part (a lattice translating together overlaps thousands of
  !> boxes per body along x: 5 s per rank for 93,312 bodies), so the ranks share it: rank
  !> r sweeps from the sorted positions r + 1, r + 1 + n_ranks, ... (interleaved, so that
  !> dense and sparse stretches of x are shared alike) and stops at its first pair. The first pair in
  !> the one-rank sweep order is the one at the smallest sorted position any rank found
  !> (one MPI_Allreduce MIN), so every rank count names the same pair.
  logical function contact_possible(par, shapes, bodies, duration, gravity, pair, margin) result(possible)
    type(parallel_t), intent(in) :: par
    type(shape_library_t), intent(in) :: shapes
    type(bodies_t), intent(in) :: bodies
    real(dp), intent(in) :: duration      !< t_end - t0 [s]
    real(dp), intent(in) :: gravity(3)    !< [m/s^2]
    real(dp), intent(in) :: margin        !< [m]
    integer(i8), intent(out) :: pair(2)   !< global ids of the first pair found (if any)
    real(dp), allocatable :: lower(:, :), upper(:, :), reach(:), x(:, :), v(:, :)
    real(dp), allocatable :: lx(:), ly(:), lz(:), ux(:), uy(:), uz(:)
    integer(i8), allocatable :: gid(:)
    logical, allocatable :: fixed(:)
    integer, allocatable :: order(:)
    integer :: n, i, a, b, k
    integer(i8) :: found, first
    real(dp) :: r, t_turn, c
    n = bodies%n_owned
    pair = 0
    allocate (lower(3, n), upper(3, n), reach(n))
    do i = 1, n
      r = shapes%shapes(bodies%shape_id(i))%bounding_radius + 0.5_dp*margin
      reach(i) = r
      lower(:, i) = bodies%x(:, i)
      upper(:, i) = bodies%x(:, i)
      if (.not. bodies%fixed(i)) then
        do k = 1, 3
          c = bodies%x(k, i) + bodies%v(k, i)*duration + 0.5_dp*gravity(k)*duration**2
          lower(k, i) = min(lower(k, i), c)
          upper(k, i) = max(upper(k, i), c)
          if (gravity(k) /= 0.0_dp) then
            t_turn = -bodies%v(k, i)/gravity(k)
            if (t_turn > 0.0_dp .and. t_turn < duration) then
              c = bodies%x(k, i) + bodies%v(k, i)*t_turn + 0.5_dp*gravity(k)*t_turn**2
              lower(k, i) = min(lower(k, i), c)
              upper(k, i) = max(upper(k, i), c)
            end if
          end if
        end do
      end if
      ! (a relative margin for the round-off of the arc's end points)
      r = r*(1.0_dp + 1.0e-9_dp) + 1.0e-9_dp*maxval(abs(upper(:, i)))
      lower(:, i) = lower(:, i) - r
      upper(:, i) = upper(:, i) + r
    end do
    call sort_index_real(lower(1, :), order)
    ! Everything the sweep reads, in sorted order and one array per coordinate: consecutive
    ! candidates are then neighbours in memory (through order they are scattered over all n
    ! bodies). With the boxes tested axis by axis, y and z first (they tell most boxes that
    ! overlap along x apart), the sweep ran 1.5x faster for 93,312 bodies.
    lx = lower(1, order)
    ly = lower(2, order)
    lz = lower(3, order)
    ux = upper(1, order)
    uy = upper(2, order)
    uz = upper(3, order)
    reach = reach(order)
    x = bodies%x(:, order)
    v = bodies%v(:, order)
    fixed = bodies%fixed(order)
    gid = bodies%gid(order)
    found = huge(1_i8)
    sweep: do a = 1 + par%rank, n, par%n_ranks
      do b = a + 1, n
        if (lx(b) > ux(a)) exit
        if (ly(b) > uy(a) .or. ly(a) > uy(b) .or. lz(b) > uz(a) .or. lz(a) > uz(b) .or. lx(a) > ux(b)) cycle
        if (fixed(a) .and. fixed(b)) cycle
        ! Two free bodies under the same gravity move linearly relative to each other:
        ! the closest approach of their centres over [0, duration] is exact.
        if (.not. (fixed(a) .or. fixed(b))) then
          if (closest_approach(x(:, b) - x(:, a), v(:, b) - v(:, a), duration) > &
              (reach(a) + reach(b))*(1.0_dp + 1.0e-9_dp)) cycle
        end if
        found = a
        pair = [min(gid(a), gid(b)), max(gid(a), gid(b))]
        exit sweep
      end do
    end do sweep
    first = par%min(found)
    possible = first < huge(1_i8)
    ! one rank holds the first pair (sorted position first is its alone): the others add 0
    if (found /= first) pair = 0
    pair(1) = par%sum(pair(1))
    pair(2) = par%sum(pair(2))
  end function contact_possible

  !> The smallest |d + u t| over 0 <= t <= duration [m].
  pure real(dp) function closest_approach(d, u, duration) result(distance)
    real(dp), intent(in) :: d(3), u(3), duration
    real(dp) :: t
    t = 0.0_dp
    if (dot_product(u, u) > 0.0_dp) t = min(max(-dot_product(d, u)/dot_product(u, u), 0.0_dp), duration)
    distance = norm2(d + u*t)
  end function closest_approach

end module ownership
