!> Broad phase: the grid's candidate pairs against a brute-force O(n^2) inflated bounding-box
!> overlap on random scenes (uniform gas, clusters, very different sizes, a walled container,
!> far from the origin). The filter is exact box arithmetic, so the comparison is exact: the
!> same pairs in the same order, no tolerance.
program test_bucket_grid
  use kinds, only: dp, i8
  use error_status, only: error_t
  use bucket_grid, only: bucket_grid_t, bucket_stats_t, choose_box_size
  use assertions
  implicit none
  type(error_t) :: err
  type(bucket_grid_t) :: grid

  call seed_random()
  call check_uniform_gas()
  call check_clusters()
  call check_mixed_sizes()
  call check_container()
  call check_far_from_origin()
  call check_errors()
  call test_finish()

contains

  subroutine seed_random()
    integer :: k
    integer, allocatable :: seed(:)
    call random_seed(size=k)
    allocate (seed(k))
    seed = 20261122 + 7919*[(k, k=1, size(seed))]
    call random_seed(put=seed)
  end subroutine seed_random

  !> n random cubes: centres uniform in [c0 - half_width, c0 + half_width], edges in [emin, emax].
  subroutine random_cubes(n, c0, half_width, emin, emax, lower, upper)
    integer, intent(in) :: n
    real(dp), intent(in) :: c0(3), half_width, emin, emax
    real(dp), intent(out) :: lower(3, n), upper(3, n)
    real(dp) :: x(3, n), e(n)
    integer :: i
    call random_number(x)
    call random_number(e)
    do i = 1, n
      x(:, i) = c0 + half_width*(2.0_dp*x(:, i) - 1.0_dp)
      e(i) = emin + (emax - emin)*e(i)
      lower(:, i) = x(:, i) - 0.5_dp*e(i)
      upper(:, i) = x(:, i) + 0.5_dp*e(i)
    end do
  end subroutine random_cubes

  !> Reference: every pair i<j, not both static, whose inflated boxes overlap, in (i, j) order.
  subroutine brute_pairs(n, lower, upper, is_static, margin, pairs, np)
    integer, intent(in) :: n
    real(dp), intent(in) :: lower(3, n), upper(3, n), margin(n)
    logical, intent(in) :: is_static(n)
    integer, allocatable, intent(out) :: pairs(:, :)
    integer, intent(out) :: np
    integer :: i, j, pass
    do pass = 1, 2
      np = 0
      do i = 1, n
        do j = i + 1, n
          if (is_static(i) .and. is_static(j)) cycle
          if (all(lower(:, i) - margin(i) <= upper(:, j) + margin(j)) .and. &
              all(lower(:, j) - margin(j) <= upper(:, i) + margin(i))) then
            np = np + 1
            if (pass == 2) pairs(:, np) = [i, j]
          end if
        end do
      end do
      if (pass == 1) allocate (pairs(2, max(1, np)))
    end do
  end subroutine brute_pairs

  !> Grid pairs (rings, margin) equal brute force exactly; returns the grid's pairs.
  subroutine compare_with_brute(what, n, lower, upper, is_static, rings, margin, pairs, np)
    character(len=*), intent(in) :: what
    integer, intent(in) :: n, rings
    real(dp), intent(in) :: lower(3, n), upper(3, n), margin(n)
    logical, intent(in) :: is_static(n)
    integer, allocatable, intent(inout) :: pairs(:, :)
    integer, intent(out) :: np
    integer, allocatable :: ref(:, :)
    integer :: nref
    character(len=160) :: msg
    call grid%build(n, lower, upper, is_static, err)
    call check(err%ok(), what//': build succeeds')
    call grid%candidate_pairs(rings, margin, pairs, np, err)
    call check(err%ok(), what//': query succeeds')
    call brute_pairs(n, lower, upper, is_static, margin, ref, nref)
    write (msg, '(a,i0,a,i0,a)') what//': grid finds ', np, ' pairs, brute force ', nref, ' (same set, same order)'
    if (np == nref) then
      call check(all(pairs(:, 1:np) == ref(:, 1:nref)), trim(msg))
    else
      call check(.false., trim(msg))
    end if
    ! a test that could pass vacuously on an empty scene would be a defect
    call check(nref > 0, what//': the scene has overlapping pairs to find')
  end subroutine compare_with_brute

  subroutine check_uniform_gas()
    integer, parameter :: n = 2000
    real(dp) :: lower(3, n), upper(3, n), margin(n), h, rnd(n)
    logical :: is_static(n)
    integer, allocatable :: pairs(:, :), pairs_b(:, :), pairs0(:, :)
    integer :: np, np_b, np0, p, q
    logical :: subset
    type(bucket_stats_t) :: st

    ! edges 0.01..0.02 m in a 0.6 m cube centred on the origin (negative coordinates too)
    call random_cubes(n, [0.0_dp, 0.0_dp, 0.0_dp], 0.3_dp, 0.01_dp, 0.02_dp, lower, upper)
    is_static = .false.
    call choose_box_size(maxval(upper - lower, dim=1), 1.0_dp, h, err)
    call check(err%ok(), 'gas: box size chosen')
    ! the smallest body sets the box (min extent is random, so compare with minval directly)
    call check_close(h, minval(maxval(upper - lower, dim=1)), 0.0_dp, 'gas: box size = smallest extent')
    call grid%init(h, err)
    call check(err%ok(), 'gas: init')
    call check_close(grid%max_step_displacement(), h, 0.0_dp, 'gas: one box per step')

    ! one ring, margins up to h/2 (their sum reaches one box)
    margin = 0.5_dp*h
    call compare_with_brute('gas, 1 ring, margin h/2', n, lower, upper, is_static, 1, margin, pairs, np)
    st = grid%stats()
    call check(st%n_grid == n .and. st%n_large == 0, 'gas: every body in the grid')
    call check(.not. st%dense, 'gas: dilute scene (3 % of the volume) uses the hash table')
    ! with h = smallest extent and edges <= 2h, each body touches <= 3 boxes per axis
    call check(st%n_entries <= 27*n .and. st%cells_used <= st%n_entries, 'gas: bounded entries per body')
    call check(st%table_size >= 2*st%n_entries, 'gas: hash load <= 1/2')
    call check(st%pairs_returned == np .and. st%pairs_tested >= np, 'gas: statistics consistent')

    ! two rings, per-body margins up to one box (time of contact)
    call random_number(rnd)
    margin = h*rnd
    call compare_with_brute('gas, 2 rings, margin in [0,h]', n, lower, upper, is_static, 2, margin, pairs_b, np_b)

    ! zero margins: one and two rings give the same pairs (the rings only cap the search)
    margin = 0.0_dp
    call grid%candidate_pairs(1, margin, pairs0, np0, err)
    call grid%candidate_pairs(2, margin, pairs, np, err)
    call check(err%ok() .and. np == np0, 'gas: zero margin, rings 1 and 2 agree in count')
    if (np == np0) call check(all(pairs(:, 1:np) == pairs0(:, 1:np0)), 'gas: zero margin, rings 1 and 2 agree')
    ! the two-ring, margin-h set contains every zero-margin pair (superset of touching pairs)
    call grid%candidate_pairs(2, [h], pairs, np, err)
    call check(err%ok() .and. np > np0, 'gas: two rings with margin h find more pairs than touching')
    subset = .true.
    q = 1
    do p = 1, np0    ! both lists sorted: merge walk
      do while (q <= np)
        if (pairs(1, q) > pairs0(1, p) .or. (pairs(1, q) == pairs0(1, p) .and. pairs(2, q) >= pairs0(2, p))) exit
        q = q + 1
      end do
      if (q > np) then
        subset = .false.
      else if (any(pairs(:, q) /= pairs0(:, p))) then
        subset = .false.
      end if
    end do
    call check(subset, 'gas: touching pairs are a subset of the two-ring candidates')

    ! owned and ghost bodies: with the last half ghosts, ghost-ghost pairs are dropped
    call grid%candidate_pairs(2, [h], pairs_b, np_b, err, n_owned=n/2)
    call check(np_b == count(pairs(1, 1:np) <= n/2) .and. np_b < np, 'gas: ghost-ghost pairs dropped, count')
    if (np_b == count(pairs(1, 1:np) <= n/2)) &
      call check(all(pairs_b(:, 1:np_b) == reshape(pack(pairs(:, 1:np), spread(pairs(1, 1:np) <= n/2, 1, 2)), &
                                                   [2, np_b])), 'gas: ghost-ghost pairs dropped, the rest kept')

    ! determinism: a second query and a rebuild give identical output
    call grid%candidate_pairs(2, [h], pairs_b, np_b, err)
    call check(np_b == np, 'gas: repeated query, same count')
    if (np_b == np) call check(all(pairs_b(:, 1:np) == pairs(:, 1:np)), 'gas: repeated query, same pairs')
    call grid%build(n, lower, upper, is_static, err)
    call grid%candidate_pairs(2, [h], pairs_b, np_b, err)
    call check(np_b == np, 'gas: rebuild, same count')
    if (np_b == np) call check(all(pairs_b(:, 1:np) == pairs(:, 1:np)), 'gas: rebuild, same pairs')
    ! strictly increasing (i, j), i < j: sorted and no duplicates
    call check(all(pairs(1, 1:np) < pairs(2, 1:np)), 'gas: i < j in every pair')
    call check(all(pairs(1, 2:np) > pairs(1, 1:np - 1) .or. (pairs(1, 2:np) == pairs(1, 1:np - 1) .and. &
                                                              pairs(2, 2:np) > pairs(2, 1:np - 1))), &
               'gas: pairs strictly increasing (sorted, unique)')
  end subroutine check_uniform_gas

  !> Five tight clusters of heavily overlapping bodies: many bodies per box.
  subroutine check_clusters()
    integer, parameter :: n = 1500
    real(dp) :: lower(3, n), upper(3, n), margin(n), h, rnd(n)
    logical :: is_static(n)
    integer, allocatable :: pairs(:, :)
    integer :: np, c, i0
    type(bucket_stats_t) :: st
    real(dp) :: centre(3)
    do c = 1, 5
      call random_number(centre)
      i0 = (c - 1)*(n/5)
      call random_cubes(n/5, 10.0_dp*centre - 5.0_dp, 0.05_dp, 0.01_dp, 0.03_dp, &
                        lower(:, i0 + 1:i0 + n/5), upper(:, i0 + 1:i0 + n/5))
    end do
    is_static = .false.
    call choose_box_size(maxval(upper - lower, dim=1), 1.5_dp, h, err)
    call grid%init(h, err)
    call random_number(rnd)
    margin = 0.5_dp*h*rnd
    call compare_with_brute('clusters, 1 ring', n, lower, upper, is_static, 1, margin, pairs, np)
    st = grid%stats()
    call check(st%max_per_cell > 10, 'clusters: crowded boxes (the scene tests many bodies per box)')
    call check(.not. st%dense, 'clusters: sparse scene uses the hash table')
    margin = h*rnd
    call compare_with_brute('clusters, 2 rings', n, lower, upper, is_static, 2, margin, pairs, np)
  end subroutine check_clusters

  !> Edges spread over two decades: bodies bigger than ~3 boxes leave the grid for the
  !> large-body hierarchy; a few static bodies of all sizes too.
  subroutine check_mixed_sizes()
    integer, parameter :: n = 1200
    real(dp) :: lower(3, n), upper(3, n), margin(n), h, rnd(n), e(n), x(3, n)
    logical :: is_static(n)
    integer, allocatable :: pairs(:, :)
    integer :: np, i
    type(bucket_stats_t) :: st
    call random_number(x)
    call random_number(e)
    do i = 1, n
      e(i) = 0.01_dp*100.0_dp**e(i)   ! log-uniform in [0.01, 1] m
      x(:, i) = 4.0_dp*x(:, i) - 2.0_dp
      lower(:, i) = x(:, i) - 0.5_dp*e(i)
      upper(:, i) = x(:, i) + 0.5_dp*e(i)
    end do
    is_static = .false.
    is_static(1:n:17) = .true.
    call choose_box_size(pack(e, .not. is_static), 1.0_dp, h, err)
    call grid%init(h, err)
    call random_number(rnd)
    margin = 0.5_dp*h*rnd
    call compare_with_brute('mixed sizes, 1 ring', n, lower, upper, is_static, 1, margin, pairs, np)
    st = grid%stats()
    call check(st%n_large > 50 .and. st%n_grid > 50, 'mixed sizes: both the grid and the hierarchy are used')
    call check(.not. st%dense, 'mixed sizes: sparse scene uses the hash table')
    ! large bodies may carry any margin: they have no ring limit
    where (e > 4.0_dp*h) margin = 0.3_dp
    call compare_with_brute('mixed sizes, large margins on large bodies', n, lower, upper, is_static, 2, &
                            margin, pairs, np)
    call check(.not. any(is_static(pairs(1, 1:np)) .and. is_static(pairs(2, 1:np))), &
               'mixed sizes: no static-static pair')
    ! max_span = 1: every body spanning two boxes goes to the hierarchy (large-large pairs)
    call grid%init(h, err, max_span=1)
    margin = 0.5_dp*h*rnd
    call compare_with_brute('mixed sizes, max_span 1', n, lower, upper, is_static, 1, margin, pairs, np)
    st = grid%stats()
    call check(st%n_large > n/2, 'mixed sizes, max_span 1: most bodies in the hierarchy')
  end subroutine check_mixed_sizes

  !> A 1 m container (floor and four walls, 5 static boxes) holding 10,000 bodies of 0.01 m:
  !> the boxes follow the small bodies, the walls stay out of the grid, and only bodies near
  !> a wall get a static-dynamic pair.
  subroutine check_container()
    integer, parameter :: nb = 10000, nw = 5, n = nb + nw
    real(dp), parameter :: t = 0.05_dp   ! wall thickness [m]
    real(dp), allocatable :: lower(:, :), upper(:, :), margin(:)
    logical, allocatable :: is_static(:)
    real(dp) :: h
    integer, allocatable :: pairs(:, :)
    integer :: np, p, i, n_wall_pairs, n_near
    type(bucket_stats_t) :: st
    logical :: near
    allocate (lower(3, n), upper(3, n), margin(n), is_static(n))
    ! walls first (indices 1..5) so that wall pairs are (wall, body)
    lower(:, 1) = [-t, -t, -t]; upper(:, 1) = [1.0_dp + t, 1.0_dp + t, 0.0_dp]        ! floor
    lower(:, 2) = [-t, -t, 0.0_dp]; upper(:, 2) = [0.0_dp, 1.0_dp + t, 1.0_dp]        ! x = 0
    lower(:, 3) = [1.0_dp, -t, 0.0_dp]; upper(:, 3) = [1.0_dp + t, 1.0_dp + t, 1.0_dp] ! x = 1
    lower(:, 4) = [-t, -t, 0.0_dp]; upper(:, 4) = [1.0_dp + t, 0.0_dp, 1.0_dp]        ! y = 0
    lower(:, 5) = [-t, 1.0_dp, 0.0_dp]; upper(:, 5) = [1.0_dp + t, 1.0_dp + t, 1.0_dp] ! y = 1
    ! bodies of edge 0.01 m inside, a few of them within their margin of a wall
    call random_cubes(nb, [0.5_dp, 0.5_dp, 0.5_dp], 0.495_dp, 0.01_dp, 0.01_dp, &
                      lower(:, nw + 1:n), upper(:, nw + 1:n))
    is_static = .false.
    is_static(1:nw) = .true.
    call choose_box_size(maxval(upper(:, nw + 1:n) - lower(:, nw + 1:n), dim=1), 1.0_dp, h, err)
    call check(h <= 0.01_dp, 'container: box size follows the small bodies, not the walls')
    call grid%init(h, err)
    margin = 0.5_dp*h
    margin(1:nw) = 0.0_dp
    call compare_with_brute('container', n, lower, upper, is_static, 1, margin, pairs, np)
    st = grid%stats()
    call check(st%n_large == nw .and. st%n_grid == nb, 'container: walls kept out of the grid')
    ! boxes used ~ n: each body touches at most 2 boxes per axis (edge <= h)
    call check(st%cells_used <= 8*nb .and. st%n_entries <= 8*nb, 'container: boxes used stay O(n)')
    ! work O(n): the bodies test their few neighbours and a handful of hierarchy leaves
    call check(st%pairs_tested <= 60_i8*nb, 'container: bounding-box tests O(n)')
    ! wall pairs exactly for the bodies whose inflated box reaches a wall
    n_wall_pairs = count(pairs(1, 1:np) <= nw)
    n_near = 0
    do i = nw + 1, n
      near = any(lower(:, i) - margin(i) <= 0.0_dp) .or. lower(1, i) - margin(i) <= 0.0_dp .or. &
             any(upper(1:2, i) + margin(i) >= 1.0_dp)
      if (near) n_near = n_near + 1
    end do
    call check(n_wall_pairs >= n_near .and. n_near > 0, 'container: every body near a wall has a wall pair')
    call check(all([(any(lower(:, pairs(2, p)) - margin(pairs(2, p)) <= 0.0_dp) .or. &
                     any(upper(1:2, pairs(2, p)) + margin(pairs(2, p)) >= 1.0_dp), &
                     p=1, n_wall_pairs)]), 'container: wall pairs only for bodies near a wall')
    call check(n_wall_pairs < nb/5, 'container: most bodies have no wall pair')
  end subroutine check_container

  !> The gas moved to (-1e6, -3.7e5, 1e6) m (10^8 boxes out) and a grid with a shifted origin.
  subroutine check_far_from_origin()
    integer, parameter :: n = 1500
    real(dp) :: lower(3, n), upper(3, n), margin(n), h, rnd(n)
    logical :: is_static(n)
    integer, allocatable :: pairs(:, :), pairs_near(:, :)
    integer :: np, np_near
    type(bucket_stats_t) :: st
    real(dp), parameter :: shift(3) = [-1.0e6_dp, -3.7e5_dp, 1.0e6_dp]
    integer :: i
    ! packed densely (bodies overlap: ~1.2 of the volume) so the dense slots are used
    call random_cubes(n, [0.0_dp, 0.0_dp, 0.0_dp], 0.08_dp, 0.01_dp, 0.02_dp, lower, upper)
    is_static = .false.
    call choose_box_size(maxval(upper - lower, dim=1), 1.0_dp, h, err)
    call grid%init(h, err)
    call random_number(rnd)
    margin = h*rnd
    call compare_with_brute('near origin, 2 rings', n, lower, upper, is_static, 2, margin, pairs_near, np_near)
    st = grid%stats()
    call check(st%dense, 'dense scene uses dense slots')
    do i = 1, n
      lower(:, i) = lower(:, i) + shift
      upper(:, i) = upper(:, i) + shift
    end do
    call compare_with_brute('far (1e6 m), 2 rings', n, lower, upper, is_static, 2, margin, pairs, np)
    ! h <= 0.02 m, so the shift is more than 10^7 boxes along every axis
    call check(all(grid%box_of_point(shift)*sign(1.0_dp, shift) > 10**7_i8), &
               'far: box coordinates are global (10^7+ boxes from 0)')
    call grid%init(h, err, origin=[-3.0_dp, 2.0_dp, 1.0e5_dp])
    call check(err%ok(), 'far: init with origin')
    call compare_with_brute('far, shifted origin', n, lower, upper, is_static, 2, margin, pairs, np)
    st = grid%stats()
    call check(st%dense, 'far scene uses dense slots too')
    call check(all(grid%box_of_point([-3.0_dp, 2.0_dp, 1.0e5_dp]) == 0_i8), 'origin is the corner of box (0,0,0)')
    ! buffers reused without init: a smaller scene, then the full one again
    call compare_with_brute('far, rebuilt smaller', n/3, lower(:, 1:n/3), upper(:, 1:n/3), is_static(1:n/3), 2, &
                            margin(1:n/3), pairs, np)
    call compare_with_brute('far, rebuilt full', n, lower, upper, is_static, 2, margin, pairs, np)
    ! half the bodies moved 2^21 boxes along y and z: their boxes hash like the others'
    ! (only the low 21 bits of j and k are mixed), so only whole-key comparison separates them
    do i = 1, n, 2
      lower(2:3, i) = lower(2:3, i) + 2.0_dp**21*h
      upper(2:3, i) = upper(2:3, i) + 2.0_dp**21*h
    end do
    call compare_with_brute('far, aliased hash rows', n, lower, upper, is_static, 2, margin, pairs, np)
    st = grid%stats()
    call check(.not. st%dense, 'aliased scene uses the hash table')
    call check(all(mod(pairs(1, 1:np) - pairs(2, 1:np), 2) == 0), 'aliased: no pair across the two groups')
  end subroutine check_far_from_origin

  subroutine check_errors()
    real(dp) :: h, lower(3, 3), upper(3, 3)
    integer, allocatable :: pairs(:, :)
    integer :: np
    type(bucket_grid_t) :: g
    call err%clear()
    call choose_box_size([0.1_dp, 0.2_dp], 0.5_dp, h, err)
    call check_error(err%code, err%message, [character(len=16) :: 'scale', '>= 1 '], 'scale below 1 rejected')
    call err%clear()
    call choose_box_size([0.1_dp, -0.2_dp], 1.0_dp, h, err)
    call check_error(err%code, err%message, ['dynamic body 2'], 'negative extent named')
    call err%clear()
    call g%init(0.0_dp, err)
    call check_error(err%code, err%message, [character(len=16) :: 'box size', '> 0'], 'zero box size rejected')
    call err%clear()
    lower = 0.0_dp
    upper = 1.0_dp
    call g%build(2, lower, upper, [.false., .false.], err)
    call check_error(err%code, err%message, ['before init'], 'build before init rejected')
    call err%clear()
    call g%init(1.0_dp, err)
    upper(2, 2) = -1.0_dp
    call g%build(2, lower, upper, [.false., .false.], err)
    call check_error(err%code, err%message, [character(len=16) :: 'body 2', 'lower > upper'], 'inverted box named')
    call err%clear()
    upper = 1.0_dp
    lower(3, 1) = 1.0e300_dp
    upper(3, 1) = 1.0e300_dp
    call g%build(2, lower, upper, [.false., .false.], err)
    call check_error(err%code, err%message, [character(len=16) :: 'body 1', '2^60 boxes'], 'body too far out rejected')
    call err%clear()
    lower = 0.0_dp
    upper = 0.5_dp
    ! a third body far from everything: no pair, so no mesh query for it
    lower(:, 3) = [50.0_dp, -20.0_dp, 3.0_dp]
    upper(:, 3) = lower(:, 3) + 0.5_dp
    call g%build(3, lower, upper, [.false., .false., .false.], err)
    call check(err%ok(), 'small scene builds')
    call g%candidate_pairs(2, [0.5_dp], pairs, np, err)
    call check(err%ok() .and. np == 1, 'isolated body: one pair in the scene')
    if (np == 1) call check(all(pairs(:, 1) == [1, 2]), 'isolated body: the far body has no pair')
    call g%candidate_pairs(1, [0.6_dp], pairs, np, err)
    call check_error(err%code, err%message, [character(len=16) :: 'margins sum', 'rings*box size'], 'margins beyond one ring rejected')
    call err%clear()
    call g%candidate_pairs(2, [0.6_dp], pairs, np, err)
    call check(err%ok() .and. np == 1, 'the same margins fit two rings')
    call g%candidate_pairs(1, [real(dp) ::], pairs, np, err)
    call check_error(err%code, err%message, ['size(margin) = 0'], 'margin of wrong size rejected')
    call err%clear()
    call g%candidate_pairs(1, [0.1_dp, -0.1_dp, 0.0_dp], pairs, np, err)
    call check_error(err%code, err%message, ['margin of body 2'], 'negative margin named')
    call err%clear()
  end subroutine check_errors

end program test_bucket_grid
