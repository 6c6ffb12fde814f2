!> cell_grid (the local event loop's broad phase): regions found by overlap, large regions
!> kept out of the boxes, and box coordinates past 2^31 (a 1e4 m body in 2e-6 m boxes, the
!> size ratio 1e10 of check_stress.py `scales`): there the default-kind floor() overflowed,
!> the 1e4 m body was listed nowhere and a 1e-6 m sphere fell through it. Then the copy a
!> cross-rank window saves and restores (event_loop copy_loop): a grid copied without its
!> box table and per-body rows (swap_table), changed further (moves, removals, a rehash), restored
!> from the copy with the bodies moved since taken out and put back (restore_prepare,
!> restore_finish) answers every query as a grid
!> built afresh with the saved regions does, before and after more placements. Last, bodies
!> wandering through new boxes (each move leaves empty boxes behind) until the table is
!> rehashed at its own size, in place: the grid then answers as one built afresh. And the
!> pool the boxes' lists live in: 300 bodies crowding into few boxes and spreading out again
!> (lists outgrowing their rooms, rooms left behind until the pool is compacted), then a
!> renumbering (remap_bodies: some bodies leave, the rest are renamed in the lists): the
!> grid answers as one built afresh every time. Each case runs again with a dense block of
!> boxes (init dense_lower, dense_upper) over part of the space: the answers are the same.
program test_cell_grid
  use kinds, only: dp, i8
  use string_utils, only: str
  use error_status, only: error_t
  use cell_grid, only: cell_grid_t, cell_lists_t, LIST_N
  use random_stream, only: random_stream_t
  use assertions, only: check, test_finish
  implicit none
  type(cell_grid_t) :: grid
  type(error_t) :: err
  integer, allocatable :: found(:)
  integer :: n_found
  real(dp), parameter :: h = 2.0e-6_dp        ! box edge [m]: a 1e-6 m sphere's extent
  real(dp), parameter :: big = 1.0e4_dp       ! [m] a planet's radius: 5e9 boxes > 2^31
  real(dp), parameter :: far = 2.0_dp**40*h   ! [m] 2^40 boxes from the origin

  call grid%init(h, 4, err)
  call check(.not. err%failed(), 'init')

  ! 1: the planet, centre (0, 0, -big), top at z = 0; 2: a dust grain 1e-3 m above it
  call grid%place(1, [-big, -big, -2.0_dp*big], [big, big, 1.0e-10_dp], err)
  call check(.not. err%failed(), 'place the planet')
  call check(all(grid%lo(:, 1) == [-5000000000_i8, -5000000000_i8, -10000000000_i8]), &
             'the planet''s lower box is floor(lower/h) in 64 bits (no 32-bit overflow)')
  call check(all(grid%hi(:, 1) >= grid%lo(:, 1)), 'the planet''s box range is not empty')
  call check(grid%large(1), 'the planet spans more than max_span boxes: kept as large')
  call grid%place(2, [-2.0e-6_dp, -2.0e-6_dp, 0.998e-3_dp], [2.0e-6_dp, 2.0e-6_dp, 1.004e-3_dp], err)
  call check(.not. grid%large(2), 'the dust grain is listed in boxes')
  call grid%query(2, found, n_found, 4)
  call check(n_found == 0, 'the grain 1e-3 m above the planet''s region: no candidate')
  ! moved down to within its margin of the top
  call grid%place(2, [-2.0e-6_dp, -2.0e-6_dp, -1.0e-6_dp], [2.0e-6_dp, 2.0e-6_dp, 3.0e-6_dp], err)
  call grid%query(2, found, n_found, 4)
  call check(n_found == 1, 'the grain at the planet''s top finds one candidate')
  if (n_found == 1) call check(found(1) == 1, 'the grain finds the planet')
  call grid%query(1, found, n_found, 4)
  call check(n_found == 1, 'the planet (large) finds the grain')
  if (n_found == 1) call check(found(1) == 2, 'the planet finds the grain, by index')

  ! 3 and 4: two grains touching 2^40 boxes from the origin (box keys whose hash
  ! products would overflow int64 without the mask), 5: one a box further on
  call grid%place(3, [far, far, far], [far + 2.0e-6_dp, far + 2.0e-6_dp, far + 2.0e-6_dp], err)
  call grid%place(4, [far + 1.0e-6_dp, far, far], [far + 3.0e-6_dp, far + 2.0e-6_dp, far + 2.0e-6_dp], err)
  call check(.not. err%failed(), 'place grains 2^40 boxes out')
  call check(.not. (grid%large(3) .or. grid%large(4)), 'the far grains are listed in boxes')
  call grid%query(3, found, n_found, 4)
  call check(n_found == 1, 'a far grain finds one candidate')
  if (n_found == 1) call check(found(1) == 4, 'a far grain finds its neighbour')
  call grid%unplace(4)
  call grid%query(3, found, n_found, 4)
  call check(n_found == 0, 'an unplaced neighbour is gone')

  ! past 2^60 boxes: refused, not wrapped
  call grid%place(4, [2.0_dp**61*h, 0.0_dp, 0.0_dp], [2.0_dp**61*h + h, h, h], err)
  call check(err%failed(), 'a region 2^61 boxes out is refused')
  call grid%free()
  ! each case twice: the live grid with the hash table alone, then with a dense block over
  ! part of the space (the bodies move in and out of it); the grid built afresh to compare
  ! with has the hash table alone, so the block must not change a single answer
  call restore_without_table(.false.)
  call restore_without_table(.true.)
  call wander_and_rehash_in_place(.false.)
  call wander_and_rehash_in_place(.true.)
  call crowd_and_compact(.false.)
  call crowd_and_compact(.true.)
  call test_finish()

contains

  !> The grid journals from the save on: the copy holds neither the box table nor the
  !> per-body rows, and the restore takes the moved bodies' rows from the journal.
  subroutine restore_without_table(dense)
    logical, intent(in) :: dense
    integer, parameter :: n = 400
    type(cell_grid_t) :: live, saved, fresh
    type(cell_lists_t) :: live_lists, saved_lists
    type(error_t) :: err
    type(random_stream_t) :: rng
    real(dp) :: lower(3, n), upper(3, n), c(3)
    logical :: placed(n)
    integer :: i, k, bad
    call rng%init(7)
    call init_live(live, n, dense, 10.0_dp)
    placed = .false.
    do i = 1, n
      if (mod(i, 7) == 0) cycle          ! some never placed
      c = [rng%uniform(), rng%uniform(), rng%uniform()]*12.0_dp
      lower(:, i) = c - 0.3_dp - rng%uniform()
      upper(:, i) = c + 0.3_dp + rng%uniform()
      if (i == 5) upper(:, i) = lower(:, i) + 9.0_dp     ! one large region
      call live%place(i, lower(:, i), upper(:, i), err)
      placed(i) = .true.
    end do
    ! the save: the journal started, the holder copied with both tables set aside
    call live%start_journal()
    call live%swap_table(live_lists)
    call saved%swap_table(saved_lists)
    saved = live
    call live%swap_table(live_lists)
    call saved%swap_table(saved_lists)
    call check(.not. allocated(saved%slot_key) .and. .not. allocated(saved%region), &
               'the saved copy holds no box table and no per-body rows')
    ! the live grid goes on: moves far away (new boxes, a rehash) and removals
    do i = 1, n, 3
      if (.not. placed(i)) cycle
      c = [rng%uniform(), rng%uniform(), rng%uniform()]*40.0_dp + 50.0_dp
      call live%place(i, c - 0.5_dp, c + 0.5_dp, err)
    end do
    do i = 2, n, 11
      if (placed(i)) call live%unplace(i)
    end do
    call check(live%n_touched > 0 .and. live%n_touched < n, 'the journal holds the bodies moved since the save')
    ! the restore, as copy_loop does it
    call live%restore_prepare()
    call saved%swap_table(saved_lists)
    call live%swap_table(live_lists)
    live = saved
    call saved%swap_table(saved_lists)
    call live%swap_table(live_lists)
    call live%restore_finish()
    ! a grid built afresh with the saved regions
    call fresh%init(1.0_dp, n, err, max_span=4)
    do i = 1, n
      if (placed(i)) call fresh%place(i, lower(:, i), upper(:, i), err)
    end do
    call check(.not. err%failed(), 'grids built')
    bad = 0
    do k = 1, 2
      bad = bad + differing_queries(live, fresh, n, placed)
      if (k == 2) exit
      ! more placements on both: the rebuilt table takes inserts into its boxes in use
      do i = 1, n, 5
        if (.not. placed(i)) cycle
        c = 0.5_dp*(lower(:, i) + upper(:, i)) + 0.7_dp
        call live%place(i, c - 0.4_dp, c + 0.4_dp, err)
        call fresh%place(i, c - 0.4_dp, c + 0.4_dp, err)
      end do
    end do
    call check(bad == 0, 'a grid restored from a copy without its table and rows answers as one built afresh '// &
               '(queries differing: '//str(bad)//')')
    ! (stale entries would not show in the answers, which test the regions again, but the
    ! lists would only grow: the boxes list exactly what a fresh grid's do)
    call check(sum(live%list(LIST_N, :), mask=live%slot_used) == sum(fresh%list(LIST_N, :), mask=fresh%slot_used), &
               'the restored lists hold as many entries as a fresh grid''s ('// &
               str(sum(live%list(LIST_N, :), mask=live%slot_used))//' and '// &
               str(sum(fresh%list(LIST_N, :), mask=fresh%slot_used))//')')
  end subroutine restore_without_table

  subroutine wander_and_rehash_in_place(dense)
    logical, intent(in) :: dense
    integer, parameter :: n = 64
    type(cell_grid_t) :: live, fresh
    type(error_t) :: err
    type(random_stream_t) :: rng
    real(dp) :: c(3, n)
    integer :: i, step, n_a, bad, size_before, in_place
    call rng%init(11)
    call init_live(live, n, dense, 20.0_dp)
    do i = 1, n
      c(:, i) = [rng%uniform(), rng%uniform(), rng%uniform()]*6.0_dp
      call live%place(i, c(:, i) - 0.4_dp, c(:, i) + 0.4_dp, err)
    end do
    ! every body walks off by a box per step: n_used grows with empty boxes until a rehash
    ! at the same size drops them (n_used falls, table_size stays)
    in_place = 0
    do step = 1, 400
      size_before = live%table_size
      n_a = live%n_used
      do i = 1, n
        c(:, i) = c(:, i) + [1.0_dp, 0.25_dp*(rng%uniform() - 0.5_dp), 0.0_dp]
        if (c(1, i) > 60.0_dp) c(1, i) = c(1, i) - 60.0_dp
        call live%place(i, c(:, i) - 0.4_dp, c(:, i) + 0.4_dp, err)
      end do
      if (live%table_size == size_before .and. live%n_used < n_a) in_place = in_place + 1
    end do
    call check(.not. err%failed(), 'wandering placements')
    call check(in_place > 0, 'the table was rehashed at its own size ('//str(in_place)//' times)')
    call fresh%init(1.0_dp, n, err, max_span=4)
    do i = 1, n
      call fresh%place(i, c(:, i) - 0.4_dp, c(:, i) + 0.4_dp, err)
    end do
    bad = differing_queries(live, fresh, n, [(.true., i=1, n)])
    call check(bad == 0, 'after rehashes in place the grid answers as one built afresh (queries differing: '// &
               str(bad)//')')
  end subroutine wander_and_rehash_in_place

  subroutine crowd_and_compact(dense)
    logical, intent(in) :: dense
    integer, parameter :: n = 300
    type(cell_grid_t) :: live, fresh
    type(error_t) :: err
    type(random_stream_t) :: rng
    real(dp) :: c(3, n), spread
    integer :: i, round, bad, compactions, top_before, max_list, new_index(n), k
    logical :: kept(n)
    call rng%init(23)
    call init_live(live, n, dense, 10.0_dp)
    bad = 0
    compactions = 0
    max_list = 0
    do round = 1, 40
      ! crowding into a 2 m cube (every box lists about a hundred bodies), then spreading
      ! over 40 m (few bodies a box): lists outgrow their rooms, then leave them unused
      spread = merge(2.0_dp, 40.0_dp, mod(round, 2) == 1)
      do i = 1, n
        c(:, i) = [rng%uniform(), rng%uniform(), rng%uniform()]*spread
        top_before = live%pool_top
        call live%place(i, c(:, i) - 0.3_dp, c(:, i) + 0.3_dp, err)
        if (live%pool_top < top_before) compactions = compactions + 1
      end do
      max_list = max(max_list, maxval(live%list(LIST_N, :), mask=live%slot_used))
      call fresh%init(1.0_dp, n, err, max_span=4)
      do i = 1, n
        call fresh%place(i, c(:, i) - 0.3_dp, c(:, i) + 0.3_dp, err)
      end do
      bad = bad + differing_queries(live, fresh, n, [(.true., i=1, n)])
    end do
    call check(.not. err%failed(), 'crowding placements')
    call check(max_list > 64, 'lists outgrew their first rooms many times (longest '//str(max_list)//')')
    call check(compactions > 0, 'the pool was compacted ('//str(compactions)//' times)')
    call check(bad == 0, 'crowded and spread out, the grid answers as one built afresh (queries differing: '// &
               str(bad)//')')
    ! a renumbering: every third body leaves, the others are numbered in reverse
    k = 0
    do i = n, 1, -1
      kept(i) = mod(i, 3) /= 0
      if (kept(i)) k = k + 1
    end do
    new_index = 0
    do i = n, 1, -1
      if (.not. kept(i)) cycle
      new_index(i) = k
      k = k - 1
    end do
    call live%remap_bodies(new_index, count(kept))
    call fresh%init(1.0_dp, count(kept), err, max_span=4)
    do i = 1, n
      if (kept(i)) call fresh%place(new_index(i), c(:, i) - 0.3_dp, c(:, i) + 0.3_dp, err)
    end do
    bad = differing_queries(live, fresh, count(kept), [(.true., i=1, count(kept))])
    call check(bad == 0, 'renumbered in its lists, the grid answers as one built afresh (queries differing: '// &
               str(bad)//')')
  end subroutine crowd_and_compact

  !> The grid under test: boxes of 1 m, the hash table alone or (dense) with a dense block
  !> over [0, edge)^3, checked to be taken.
  subroutine init_live(live, n, dense, edge)
    type(cell_grid_t), intent(inout) :: live
    integer, intent(in) :: n
    logical, intent(in) :: dense
    real(dp), intent(in) :: edge
    type(error_t) :: err
    if (dense) then
      call live%init(1.0_dp, n, err, max_span=4, dense_lower=[0.0_dp, 0.0_dp, 0.0_dp], &
                     dense_upper=[1.0_dp, 1.0_dp, 1.0_dp]*(edge - 0.5_dp), max_dense=nint(edge)**3)
      call check(live%n_dense == nint(edge)**3, 'the dense block holds '//str(nint(edge)**3)//' boxes ('// &
                 str(live%n_dense)//')')
    else
      call live%init(1.0_dp, n, err, max_span=4)
    end if
    call check(.not. err%failed(), 'grid made')
  end subroutine init_live

  !> How many of the bodies 1..n with included(i) get other candidates from live than from fresh.
  integer function differing_queries(live, fresh, n, included) result(bad)
    type(cell_grid_t), intent(inout) :: live, fresh
    integer, intent(in) :: n
    logical, intent(in) :: included(:)
    integer, allocatable :: a(:), b(:)
    integer :: i, n_a, n_b
    bad = 0
    do i = 1, n
      if (.not. included(i)) cycle
      call live%query(i, a, n_a, n)
      call fresh%query(i, b, n_b, n)
      if (n_a /= n_b) then
        bad = bad + 1
      else if (any(a(1:n_a) /= b(1:n_b))) then
        bad = bad + 1
      end if
    end do
  end function differing_queries

end program test_cell_grid
