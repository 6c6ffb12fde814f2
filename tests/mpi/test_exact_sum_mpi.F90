! ctest-ranks: 4
!> Exact sums over ranks (exact_sum through parallel_env's sum_inplace) on the ranks this
!> runs on (4; test_exact_sum_mpi_2ranks includes this file for 2; 1 works too). Every
!> rank builds the same seeded terms, 14 columns of them (wide-range values, values that
!> cancel, subnormals), and the same one-rank reference sums; then the terms are split
!> over the ranks in several ways (blocks, round robin, a random owner per term, all on
!> the last rank, uneven blocks), each rank adding its share in its own shuffled order:
!> after the reduction every rank's sums must be bitwise the reference. Non-finite terms
!> on some ranks give every rank NaN or the infinity. Then compute_totals of a seeded
!> scene split over the ranks the same ways: every total bitwise that of one rank holding
!> every body. The plain floating-point sums are printed beside, for comparison only.
program test_exact_sum_mpi
  use, intrinsic :: iso_fortran_env, only: output_unit
  use, intrinsic :: ieee_arithmetic, only: ieee_is_nan, ieee_value, ieee_positive_inf, ieee_negative_inf
  use kinds, only: dp, i8
  use parallel_env, only: parallel_t
  use exact_sum, only: exact_sum_t
  use random_stream, only: random_stream_t
  use body_state, only: bodies_t
  use conservation, only: system_totals_t, compute_totals
  use body_fixtures, only: filled_bodies
  use string_utils, only: str
  use assertions
  implicit none

  integer, parameter :: N_TERMS = 3000, N_COLUMNS = 14, N_BODIES = 400
  integer, parameter :: N_SPLITS = 5
  character(len=*), parameter :: SPLIT_NAMES(N_SPLITS) = [character(len=12) :: 'blocks', 'round robin', &
                                                          'random owner', 'last rank', 'uneven']
  type(parallel_t) :: par
  real(dp), allocatable :: terms(:, :)
  real(dp) :: reference(N_COLUMNS)
  integer :: split

  call par%init()
  call make_terms(terms, reference)
  do split = 1, N_SPLITS
    call one_split(split)
  end do
  call non_finite()
  do split = 1, N_SPLITS
    call totals_split(split)
  end do
  call par%free()
  call test_finish()

contains

  logical function same(a, b)
    real(dp), intent(in) :: a, b
    same = transfer(a, 0_i8) == transfer(b, 0_i8)
  end function same

  !> The rank that holds item i (1..n) of n under a split (the same on every rank).
  function owners(kind, n) result(owner)
    integer, intent(in) :: kind, n
    integer :: owner(n)
    type(random_stream_t) :: rng
    integer :: i, p
    p = par%n_ranks
    select case (kind)
    case (1)
      owner = [((i - 1)*p/n, i=1, n)]
    case (2)
      owner = [(mod(i, p), i=1, n)]
    case (3)
      call rng%init(777)
      do i = 1, n
        owner(i) = min(int(rng%uniform()*p), p - 1)
      end do
    case (4)
      owner = p - 1
    case default
      ! rank r holds a block of length proportional to (r + 1)^2
      do i = 1, n
        owner(i) = p - 1
        do
          if (owner(i) == 0) exit
          if (real(i - 1, dp)/n < cum(owner(i) - 1, p)) then
            owner(i) = owner(i) - 1
          else
            exit
          end if
        end do
      end do
    end select
  end function owners

  pure real(dp) function cum(r, p)
    integer, intent(in) :: r, p
    integer :: k
    cum = real(sum([((k + 1)**2, k=0, r)]), dp)/real(sum([((k + 1)**2, k=0, p - 1)]), dp)
  end function cum

  !> This rank's rows of the items it holds, in an order of its own (shuffled by rank).
  function my_items(owner) result(rows)
    integer, intent(in) :: owner(:)
    integer, allocatable :: rows(:)
    type(random_stream_t) :: rng
    integer :: i, j, t
    rows = pack([(i, i=1, size(owner))], owner == par%rank)
    call rng%init(1000 + par%rank)
    do i = size(rows), 2, -1
      j = min(1 + int(rng%uniform()*i), i)
      t = rows(i)
      rows(i) = rows(j)
      rows(j) = t
    end do
  end function my_items

  !> Columns: 1-4 values (1 + u) 2^k of k in -30..30, 5-8 random finite bit patterns each
  !> with its negative and a small remainder, 9-10 subnormals and tiny values, 11-14
  !> physics-like terms (m v^2/2, m x with x of 1e6 and cancelling signs).
  subroutine make_terms(t, ref)
    real(dp), allocatable, intent(out) :: t(:, :)
    real(dp), intent(out) :: ref(N_COLUMNS)
    type(random_stream_t) :: rng
    type(exact_sum_t) :: acc(N_COLUMNS)
    integer(i8) :: bits
    integer :: i, c
    allocate (t(N_COLUMNS, N_TERMS))
    call rng%init(4242)
    do i = 1, N_TERMS
      do c = 1, 4
        t(c, i) = sign(scale(1.0_dp + rng%uniform(), int(rng%uniform()*61) - 30), rng%symmetric(1.0_dp))
      end do
      do c = 5, 8
        if (mod(i, 2) == 1) then
          do
            bits = rng%next_u64()
            if (ibits(bits, 52, 11) /= 2047) exit
          end do
          t(c, i) = transfer(bits, 1.0_dp)
        else
          t(c, i) = -t(c, i - 1)
        end if
        if (i == N_TERMS/2) t(c, i) = real(c, dp)*1.0e-3_dp
      end do
      t(9, i) = scale(rng%uniform(), -1060)
      t(10, i) = sign(scale(rng%uniform(), -1022 + int(rng%uniform()*4)), rng%symmetric(1.0_dp))
      t(11, i) = 0.5_dp*(1.0_dp + rng%uniform())*rng%symmetric(3.0_dp)**2
      t(12, i) = (1.0_dp + rng%uniform())*(1.0e6_dp + rng%symmetric(10.0_dp))
      t(13, i) = (1.0_dp + rng%uniform())*rng%symmetric(1.0e6_dp)
      t(14, i) = rng%symmetric(1.0e-8_dp)
    end do
    do i = 1, N_TERMS
      call acc%add(t(:, i))
    end do
    ref = acc%value()
  end subroutine make_terms

  subroutine one_split(kind)
    integer, intent(in) :: kind
    type(exact_sum_t) :: acc(N_COLUMNS), column
    integer, allocatable :: rows(:)
    real(dp) :: plain(N_COLUMNS)
    integer, parameter :: PLAIN_COLUMNS(8) = [1, 2, 3, 4, 11, 12, 13, 14]   ! where a plain sum cannot overflow
    integer :: k, c, n_differ
    logical :: ok
    rows = my_items(owners(kind, N_TERMS))
    call check(par%sum(size(rows)) == N_TERMS, trim(SPLIT_NAMES(kind))//': every term held once')
    plain = 0.0_dp
    do k = 1, size(rows)
      call acc%add(terms(:, rows(k)))
      plain(PLAIN_COLUMNS) = plain(PLAIN_COLUMNS) + terms(PLAIN_COLUMNS, rows(k))
    end do
    call par%sum_inplace(acc)
    ok = .true.
    do c = 1, N_COLUMNS
      ok = ok .and. same(acc(c)%value(), reference(c))
    end do
    call check(ok, trim(SPLIT_NAMES(kind))//' on '//str(par%n_ranks)//' ranks: all 14 sums bitwise the one-rank sums')
    ! the scalar form, column 12 alone, added as one array
    call column%add_array(terms(12, rows))
    call par%sum_inplace(column)
    call check(same(column%value(), reference(12)), trim(SPLIT_NAMES(kind))//': one accumulator alone')
    ! for comparison: how many plain floating-point sums differ from the exact ones
    call par%sum_inplace(plain)
    n_differ = count([(.not. same(plain(PLAIN_COLUMNS(c)), reference(PLAIN_COLUMNS(c))), c=1, 8)])
    if (par%is_root()) write (output_unit, '(a)') trim(SPLIT_NAMES(kind))//': plain sums differing from the exact ones: '// &
      str(n_differ)//' of 8'
  end subroutine one_split

  subroutine non_finite()
    type(exact_sum_t) :: a(3)
    real(dp) :: inf, minus_inf
    inf = ieee_value(inf, ieee_positive_inf)
    minus_inf = ieee_value(minus_inf, ieee_negative_inf)
    call a%add([1.0_dp, 1.0_dp, huge(1.0_dp)])
    if (par%rank == par%n_ranks - 1) call a(1)%add(inf)
    if (par%rank == 0) call a(2)%add(inf)
    if (par%rank == par%n_ranks - 1) call a(2)%add(minus_inf)
    call par%sum_inplace(a)
    call check(same(a(1)%value(), inf), '+Inf on the last rank: +Inf on every rank')
    call check(ieee_is_nan(a(2)%value()), '+Inf on rank 0 and -Inf on the last: NaN on every rank')
    if (par%n_ranks > 1) then
      call check(same(a(3)%value(), inf), 'huge on every rank: beyond the range, +Inf')
    else
      call check(same(a(3)%value(), huge(1.0_dp)), 'huge on one rank: huge')
    end if
  end subroutine non_finite

  !> compute_totals of a scene split over the ranks: bitwise those of one rank with all
  !> the bodies (a parallel_t left uninitialised is a one-rank one: it never calls MPI).
  subroutine totals_split(kind)
    integer, intent(in) :: kind
    type(parallel_t) :: solo
    type(bodies_t) :: full, mine
    type(system_totals_t) :: ref, got
    real(dp), parameter :: G(3) = [0.3_dp, -0.2_dp, -9.81_dp]
    integer :: i
    logical :: ok
    call filled_bodies(N_BODIES, 0, 99, 5000_i8, full)
    do i = 1, N_BODIES
      full%x(:, i) = full%x(:, i) + [1.0e5_dp, -3.0e4_dp, 2.0e3_dp]    ! far from the origin
      full%a(:, i) = 0.0_dp
    end do
    call compute_totals(solo, full, G, ref)
    call mine%allocate(1)
    call mine%append_rows(full, my_items(owners(kind, N_BODIES)), .false.)
    call compute_totals(par, mine, G, got)
    ok = same(got%kinetic_translational, ref%kinetic_translational) .and. &
         same(got%kinetic_rotational, ref%kinetic_rotational) .and. same(got%potential, ref%potential) .and. &
         same(got%mass, ref%mass) .and. same(got%angular_momentum_scale, ref%angular_momentum_scale)
    do i = 1, 3
      ok = ok .and. same(got%momentum(i), ref%momentum(i)) .and. &
           same(got%angular_momentum(i), ref%angular_momentum(i)) .and. &
           same(got%centre_of_mass(i), ref%centre_of_mass(i))
    end do
    call check(ok, 'compute_totals, '//trim(SPLIT_NAMES(kind))//' on '//str(par%n_ranks)// &
               ' ranks: every total bitwise the one-rank totals')
    call check(ref%mass > 0.0_dp .and. ref%kinetic_translational > 0.0_dp, 'the scene has moving bodies')
  end subroutine totals_split

end program test_exact_sum_mpi
