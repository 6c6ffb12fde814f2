!> Benchmark of the broad phase (not a test): build and query times of bucket_grid for a
!> uniform gas of n cubes (edge 0.01 m, volume fraction 0.2 and 0.005) for n = 10^3 .. 10^6, and a
!> walled container against the same bodies without walls. Run by tools/bench_bucket_grid.sh.
program bench_bucket_grid
  use kinds, only: dp, i8
  use error_status, only: error_t
  use bucket_grid, only: bucket_grid_t, bucket_stats_t, choose_box_size
  implicit none
  integer, parameter :: n_sizes = 7
  integer, parameter :: sizes(n_sizes) = [1000, 3000, 10000, 30000, 100000, 300000, 1000000]
  real(dp), parameter :: edge = 0.01_dp
  real(dp) :: phi
  integer :: k, nmax, pass
  integer :: seed_size
  integer, allocatable :: seed(:)
  real(dp) :: t(n_sizes, 3), slope(3)

  call random_seed(size=seed_size)
  allocate (seed(seed_size))
  seed = 12345
  call random_seed(put=seed)
  nmax = sizes(n_sizes)
  if (command_argument_count() > 0) nmax = 100000   ! quick mode
  do pass = 1, 2
    ! dense gas (dense slots), then dilute gas (hash table)
    phi = merge(0.2_dp, 0.005_dp, pass == 1)
    write (*, '(a,f6.3,a)') '# uniform gas, edge 0.01 m, volume fraction', phi, ', h = edge (scale 1)'
    write (*, '(a)') '#        n   build[s]  query1[s]  query2[s]  pairs1     pairs2     tested2   cells   max/cell dense'
    do k = 1, n_sizes
      if (sizes(k) > nmax) then
        t(k, :) = -1.0_dp
        cycle
      end if
      call run_gas(sizes(k), phi, t(k, :))
    end do
    ! growth exponent: least-squares slope of log t against log n over the sizes run
    do k = 1, 3
      slope(k) = fit_slope(pack(log(real(sizes, dp)), t(:, k) > 0.0_dp), pack(log(max(t(:, k), 1.0e-30_dp)), t(:, k) > 0.0_dp))
    end do
    write (*, '(a,3f7.3)') '# growth exponent (build, query 1 ring, query 2 rings): ', slope
  end do
  call run_container(10000)
  call run_container(100000)

contains

  subroutine gas(n, side, lower, upper)
    integer, intent(in) :: n
    real(dp), intent(in) :: side
    real(dp), intent(out) :: lower(:, :), upper(:, :)
    integer :: i
    call random_number(lower(:, 1:n))
    do i = 1, n
      lower(:, i) = side*lower(:, i) - 0.5_dp*side
      upper(:, i) = lower(:, i) + edge
    end do
  end subroutine gas

  subroutine run_gas(n, phi, times)
    integer, intent(in) :: n
    real(dp), intent(in) :: phi
    real(dp), intent(out) :: times(3)
    real(dp), allocatable :: lower(:, :), upper(:, :), ext(:)
    logical, allocatable :: is_static(:)
    integer, allocatable :: pairs(:, :)
    type(bucket_grid_t) :: grid
    type(error_t) :: err
    type(bucket_stats_t) :: st
    real(dp) :: h, side
    integer :: np1, np2, rep, nrep
    integer(i8) :: c0, c1, rate
    allocate (lower(3, n), upper(3, n), ext(n), is_static(n))
    side = (n*edge**3/phi)**(1.0_dp/3.0_dp)
    call gas(n, side, lower, upper)
    is_static = .false.
    ext = edge
    call choose_box_size(ext, 1.0_dp, h, err)
    call grid%init(h, err)
    nrep = max(1, 100000/n)
    ! warm-up: a simulation rebuilds every step into buffers it already has, so first-touch
    ! page faults of fresh allocations are not timed
    call grid%build(n, lower, upper, is_static, err)
    call grid%candidate_pairs(2, [h], pairs, np2, err)
    call system_clock(c0, rate)
    do rep = 1, nrep
      call grid%build(n, lower, upper, is_static, err)
    end do
    call system_clock(c1)
    times(1) = real(c1 - c0, dp)/rate/nrep
    call system_clock(c0)
    do rep = 1, nrep
      call grid%candidate_pairs(1, [0.5_dp*h], pairs, np1, err)
    end do
    call system_clock(c1)
    times(2) = real(c1 - c0, dp)/rate/nrep
    call system_clock(c0)
    do rep = 1, nrep
      call grid%candidate_pairs(2, [h], pairs, np2, err)
    end do
    call system_clock(c1)
    times(3) = real(c1 - c0, dp)/rate/nrep
    st = grid%stats()
    if (err%failed()) write (*, '(a)') 'error: '//err%message
    write (*, '(i10,3es11.3,3i10,2i9,l3)') n, times, np1, np2, st%pairs_tested, st%cells_used, st%max_per_cell, st%dense
  end subroutine run_gas

  !> n bodies at volume fraction 0.2 in a container of 5 walls, against the same bodies alone.
  subroutine run_container(n)
    integer, intent(in) :: n
    real(dp), allocatable :: lower(:, :), upper(:, :), ext(:)
    logical, allocatable :: is_static(:)
    integer, allocatable :: pairs(:, :)
    type(bucket_grid_t) :: grid
    type(error_t) :: err
    type(bucket_stats_t) :: st
    real(dp) :: h, side, tw, tb(2)
    integer :: np, rep, nrep, case, m, i
    integer(i8) :: c0, c1, rate
    allocate (lower(3, n + 5), upper(3, n + 5), ext(n), is_static(n + 5))
    side = (n*edge**3/0.2_dp)**(1.0_dp/3.0_dp)   ! volume fraction 0.2
    tw = 0.1_dp*side
    lower(:, 1) = [-tw, -tw, -tw]; upper(:, 1) = [side + tw, side + tw, 0.0_dp]
    lower(:, 2) = [-tw, -tw, 0.0_dp]; upper(:, 2) = [0.0_dp, side + tw, side]
    lower(:, 3) = [side, -tw, 0.0_dp]; upper(:, 3) = [side + tw, side + tw, side]
    lower(:, 4) = [-tw, -tw, 0.0_dp]; upper(:, 4) = [side + tw, 0.0_dp, side]
    lower(:, 5) = [-tw, side, 0.0_dp]; upper(:, 5) = [side + tw, side + tw, side]
    call random_number(lower(:, 6:n + 5))
    do i = 6, n + 5
      lower(:, i) = (side - edge)*lower(:, i)
      upper(:, i) = lower(:, i) + edge
    end do
    is_static = .false.
    is_static(1:5) = .true.
    ext = edge
    call choose_box_size(ext, 1.0_dp, h, err)
    call grid%init(h, err)
    nrep = max(1, 300000/n)
    call grid%build(n + 5, lower, upper, is_static, err)   ! warm-up (see run_gas)
    call grid%candidate_pairs(2, [h], pairs, np, err)
    do case = 1, 2
      m = 0
      if (case == 2) m = 5   ! skip the walls
      call system_clock(c0, rate)
      do rep = 1, nrep
        call grid%build(n + 5 - m, lower(:, 1 + m:), upper(:, 1 + m:), is_static(1 + m:), err)
        call grid%candidate_pairs(2, [h], pairs, np, err)
      end do
      call system_clock(c1)
      tb(case) = real(c1 - c0, dp)/rate/nrep
      st = grid%stats()
      write (*, '(a,i8,a,l2,a,es10.3,a,i9,a,i10,a,i9)') '# container n =', n, ' walls', case == 1, &
        ': build+query2 ', tb(case), ' s, pairs', np, ', tested', st%pairs_tested, ', cells', st%cells_used
    end do
    write (*, '(a,f6.3)') '# container cost / bodies-alone cost: ', tb(1)/tb(2)
  end subroutine run_container

  pure real(dp) function fit_slope(x, y) result(b)
    real(dp), intent(in) :: x(:), y(:)
    real(dp) :: mx, my
    mx = sum(x)/size(x)
    my = sum(y)/size(y)
    b = sum((x - mx)*(y - my))/sum((x - mx)**2)
  end function fit_slope

end program bench_bucket_grid
