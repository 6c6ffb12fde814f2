!> What one time window of the domain decomposition costs in communication, measured on
!> this machine for docs/benchmarks.md section 8 (the model of efficiency at 64 and 1024
!> ranks takes these numbers): the window's one MPI_Allreduce MIN (parallel_env%min) and
!> the halo exchange of one and of two rings (halo_exchange: three staged passes, at most 6
!> payload messages), with its messages and bytes per rank.
!>
!> Scene: `per_rank` bodies per rank, `density` bodies per grid box (1 m boxes), bricks of
!> m x m x m boxes with m^3 density = per_rank, laid out by suggest_dims over the ranks
!> (`slab`: P x 1 x 1, every rank two face neighbours but the ends; `cube`: dims from
!> suggest_dims for a cubic scene). Each rank fills its own brick with bodies at random
!> positions (every field set, the rows as a migration would leave them), so the halo of
!> two rings holds about 2 x 2 m^2 density bodies per face neighbour (slab).
!>
!>   mpiexec -n P bench_window_cost [per_rank [density [slab|cube [repeats]]]]
!>
!> Prints one line per measure on rank 0: the median over `repeats` of the slowest rank's
!> time (each repeat starts after a barrier), and the counts.
program bench_window_cost
  use kinds, only: dp, i8
  use error_status, only: error_t
  use parallel_env, only: parallel_t
  use domain, only: domain_t, box_range_t, suggest_dims
  use body_state, only: bodies_t
  use halo_exchange, only: exchange_halo, halo_stats_t
  use random_stream, only: random_stream_t
  use sorting, only: sort_index_real
  implicit none

  type(parallel_t) :: par
  type(domain_t) :: dom
  type(bodies_t) :: bodies
  type(error_t) :: err
  type(halo_stats_t) :: stats
  type(random_stream_t) :: rng
  type(box_range_t) :: brick
  character(len=32) :: arg
  character(len=8) :: layout
  integer :: per_rank, repeats, dims(3), m, i, k, r, rings, fixed(3)
  real(dp) :: density, lower(3), upper(3), t0, value
  real(dp), allocatable :: times(:)
  integer(i8), allocatable :: versions(:)

  call par%init()
  per_rank = 50000
  density = 2.0_dp
  layout = 'slab'
  repeats = 200
  if (command_argument_count() >= 1) then
    call get_command_argument(1, arg)
    read (arg, *) per_rank
  end if
  if (command_argument_count() >= 2) then
    call get_command_argument(2, arg)
    read (arg, *) density
  end if
  if (command_argument_count() >= 3) call get_command_argument(3, layout)
  if (command_argument_count() >= 4) then
    call get_command_argument(4, arg)
    read (arg, *) repeats
  end if

  ! bricks of m^3 boxes; the scene is dims * m boxes along each axis
  m = max(2, nint((real(per_rank, dp)/density)**(1.0_dp/3.0_dp)))
  if (trim(layout) == 'slab') then
    dims = [par%n_ranks, 1, 1]
  else
    fixed = 0
    call suggest_dims(par%n_ranks, fixed, dims, err, [int(m, i8), int(m, i8), int(m, i8)]*int(par%n_ranks, i8))
    call stop_if_failed('suggest_dims')
  end if
  lower = 0.0_dp
  upper = real(dims*m, dp) - 0.5_dp
  call par%cart_create(dims, err)
  call stop_if_failed('cart_create')
  call dom%init(1.0_dp, lower, upper, dims, par%cart_rank, err)
  call stop_if_failed('domain')
  brick = dom%own

  ! this rank's bodies, random inside its brick, gids by rank
  call rng%init(1000 + par%rank)
  call bodies%allocate(per_rank)
  bodies%n_owned = per_rank
  bodies%n_ghost = 0
  do i = 1, per_rank
    bodies%gid(i) = int(par%rank, i8)*int(per_rank, i8) + i
    bodies%shape_id(i) = 1 + mod(i, 3)
    bodies%group_id(i) = 1
    bodies%fixed(i) = .false.
    bodies%asleep(i) = .false.
    bodies%mass(i) = 1.0_dp + rng%uniform()
    bodies%inv_mass(i) = 1.0_dp/bodies%mass(i)
    do k = 1, 3
      bodies%x(k, i) = real(brick%lo(k), dp) + real(brick%hi(k) - brick%lo(k) + 1, dp)*rng%uniform()
      bodies%x(k, i) = min(bodies%x(k, i), upper(k))
      bodies%v(k, i) = rng%symmetric(1.0_dp)
      bodies%w(k, i) = rng%symmetric(1.0_dp)
      bodies%inertia(k, i) = 1.0_dp
      bodies%inv_inertia(k, i) = 1.0_dp
    end do
    bodies%q(:, i) = [1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp]
  end do
  allocate (versions(per_rank))
  versions = 1

  if (par%is_root()) then
    write (*, '(a,i0,a,i0,a,i0,a,i0,a,i0,a,f0.2,a,i0)') 'ranks ', par%n_ranks, ' dims ', dims(1), ' x ', dims(2), &
      ' x ', dims(3), ' bodies per rank ', per_rank, ' per grid box ', density, ' brick edge (boxes) ', m
  end if

  allocate (times(repeats))
  ! the window's one allreduce (MIN of a double)
  do r = 1, repeats
    call par%barrier()
    t0 = par%wtime()
    value = par%min(real(par%rank + r, dp))
    times(r) = par%max(par%wtime() - t0)
  end do
  call report('allreduce MIN [us]', 1.0e6_dp, 0_i8, 0_i8, 0_i8)

  do rings = 1, 2
    do r = 1, repeats
      stats = halo_stats_t()
      call par%barrier()
      t0 = par%wtime()
      call exchange_halo(par, dom, bodies, rings, err, versions=versions, stats=stats)
      times(r) = par%max(par%wtime() - t0)
      call stop_if_failed('exchange_halo')
    end do
    call report('halo exchange, '//achar(48 + rings)//' ring(s) [ms]', 1.0e3_dp, &
                int(par%max(real(stats%messages_sent, dp)), i8), int(par%max(real(stats%bytes_sent, dp)), i8), &
                int(par%max(real(stats%bodies_received, dp)), i8))
  end do

  call par%free()

contains

  subroutine report(what, scale, messages, bytes, ghosts)
    character(len=*), intent(in) :: what
    real(dp), intent(in) :: scale
    integer(i8), intent(in) :: messages, bytes, ghosts
    integer, allocatable :: order(:)
    call sort_index_real(times, order)
    times = times(order)
    if (par%is_root()) write (*, '(a,t34,a,es10.3,a,es10.3,a,es10.3,a,i0,a,i0,a,i0)') what, ' median ', &
      scale*times((repeats + 1)/2), ' min ', scale*times(1), ' p90 ', scale*times(max(1, (9*repeats)/10)), &
      '  messages/rank ', messages, '  bytes/rank ', bytes, '  ghosts/rank ', ghosts
  end subroutine report

  subroutine stop_if_failed(what)
    character(len=*), intent(in) :: what
    if (par%any(err%failed())) then
      if (par%is_root()) write (*, '(a)') 'bench_window_cost: '//what//': '//trim(err%message)
      call par%abort(1)
    end if
  end subroutine stop_if_failed

end program bench_window_cost
