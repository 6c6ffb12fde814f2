!> exact_sum: the sum is exact and its value is the correctly rounded double (nearest, ties
!> to even), whatever the order of the terms and however they are grouped and merged.
!> Known sums (huge cancellations, overflow on the way and beyond the double range,
!> subnormals, steps of 2^-1074 around rounding ties); random terms against an exact
!> real128 reference, shuffled, split into random groups merged in random orders and
!> summed as integer words (what the MPI reduction does); wide-range terms that cancel in
!> pairs; NaN and infinities; headroom of the limbs under repeated merges; the elemental
!> vector form. A timing line (no assertion) gives the cost per add.
program test_exact_sum
  use, intrinsic :: iso_fortran_env, only: real128, output_unit
  use, intrinsic :: ieee_arithmetic, only: ieee_is_nan, ieee_value, ieee_positive_inf, ieee_negative_inf, &
                                           ieee_quiet_nan
  use kinds, only: dp, i8
  use exact_sum, only: exact_sum_t, EXACT_SUM_WORDS
  use random_stream, only: random_stream_t
  use string_utils, only: str
  use assertions
  implicit none

  real(dp), parameter :: TINY_SUB = 2.0_dp**(-1074)   ! the smallest subnormal
  type(random_stream_t) :: rng
  real(dp) :: inf, minus_inf

  inf = ieee_value(inf, ieee_positive_inf)
  minus_inf = ieee_value(minus_inf, ieee_negative_inf)
  call rng%init(20181)
  call known_sums()
  call rounding_ties()
  call subnormals()
  call random_against_quad()
  call wide_range_cancelling()
  call non_finite()
  call headroom()
  call vector_form()
  call timing()
  call test_finish()

contains

  logical function same(a, b)
    real(dp), intent(in) :: a, b
    same = transfer(a, 0_i8) == transfer(b, 0_i8)
  end function same

  real(dp) function sum_of(x)
    real(dp), intent(in) :: x(:)
    type(exact_sum_t) :: acc
    call acc%add_array(x)
    sum_of = acc%value()
  end function sum_of

  !> Every order of three terms (all 6 permutations) gives expected, bit for bit.
  subroutine all_orders(x, expected, what)
    real(dp), intent(in) :: x(3), expected
    character(len=*), intent(in) :: what
    integer, parameter :: P(3, 6) = reshape([1, 2, 3, 1, 3, 2, 2, 1, 3, 2, 3, 1, 3, 1, 2, 3, 2, 1], [3, 6])
    integer :: k
    logical :: ok
    ok = .true.
    do k = 1, 6
      ok = ok .and. same(sum_of(x(P(:, k))), expected)
    end do
    call check(ok, what//' in every order')
  end subroutine all_orders

  subroutine known_sums()
    type(exact_sum_t) :: acc
    call check(same(acc%value(), 0.0_dp), 'no terms: +0')
    call check(same(sum_of([1.0_dp, 2.0_dp, 3.0_dp]), 6.0_dp), '1 + 2 + 3 = 6')
    call check(same(sum_of([0.1_dp, 0.2_dp]), 0.1_dp + 0.2_dp), '0.1 + 0.2 as IEEE (one rounding)')
    call check(same(sum_of([-0.0_dp, -0.0_dp]), 0.0_dp), 'zeros sum to +0 (as a sum started at +0 does)')
    call all_orders([1.0e308_dp, 1.0e-300_dp, -1.0e308_dp], 1.0e-300_dp, '1e308 + 1e-300 - 1e308 = 1e-300')
    call all_orders([huge(1.0_dp), huge(1.0_dp), -huge(1.0_dp)], huge(1.0_dp), &
                    'huge + huge - huge = huge (no overflow on the way)')
    call all_orders([1.0_dp, 1.0e100_dp, -1.0e100_dp], 1.0_dp, '1 + 1e100 - 1e100 = 1')
    call all_orders([2.0_dp**(-1074), 2.0_dp**1023, -2.0_dp**1023], TINY_SUB, '2^-1074 + 2^1023 - 2^1023')
    call check(same(sum_of([huge(1.0_dp), huge(1.0_dp)]), inf), 'huge + huge: the exact sum is beyond range, +Inf')
    call check(same(sum_of([-huge(1.0_dp), -huge(1.0_dp)]), minus_inf), '-huge - huge: -Inf')
    ! huge has an odd mantissa: half its ulp (2^970) is a tie that rounds up, past the range
    call check(same(sum_of([huge(1.0_dp), 2.0_dp**970]), inf), 'huge + ulp/2 rounds to +Inf (tie, odd)')
    call check(same(sum_of([huge(1.0_dp), 2.0_dp**969]), huge(1.0_dp)), 'huge + ulp/4 stays huge')
    call check(same(sum_of([huge(1.0_dp), 2.0_dp**970, -2.0_dp**969]), huge(1.0_dp)), &
               'huge + ulp/2 - ulp/4: below the tie, huge')
  end subroutine known_sums

  subroutine rounding_ties()
    real(dp), parameter :: E = epsilon(1.0_dp)   ! 2^-52
    call check(same(sum_of([1.0_dp, E/2]), 1.0_dp), '1 + 2^-53: tie to even (1)')
    call check(same(sum_of([1.0_dp + E, E/2]), 1.0_dp + 2*E), '(1 + 2^-52) + 2^-53: tie to even (up)')
    call check(same(sum_of([1.0_dp, E/2, TINY_SUB]), 1.0_dp + E), '1 + 2^-53 + 2^-1074: just above the tie, up')
    call check(same(sum_of([1.0_dp, E/2, -TINY_SUB]), 1.0_dp), '1 + 2^-53 - 2^-1074: just below the tie, down')
    call check(same(sum_of([1.0_dp, TINY_SUB]), 1.0_dp), '1 + 2^-1074 = 1')
    call check(same(sum_of([1.0_dp, -TINY_SUB]), 1.0_dp), '1 - 2^-1074 = 1')
    call check(same(sum_of([1.0_dp, -E/4]), 1.0_dp), '1 - 2^-54: tie to even (1)')
    call check(same(sum_of([1.0_dp, -E/4, -TINY_SUB]), 1.0_dp - E/2), '1 - 2^-54 - 2^-1074: down')
    call check(same(sum_of([-1.0_dp, -E/2, -TINY_SUB]), -1.0_dp - E), 'negative: -1 - 2^-53 - 2^-1074')
    call check(same(sum_of([-1.0_dp - E, -E/2]), -1.0_dp - 2*E), 'negative tie to even')
    ! 2^53 + 1 units of 2^-1074: the first sum that needs rounding (54 bits)
    call check(same(sum_of([2.0_dp**(-1021), TINY_SUB]), 2.0_dp**(-1021)), '2^-1021 + 2^-1074: tie to even')
    call check(same(sum_of([2.0_dp**(-1021), 3*TINY_SUB]), 2.0_dp**(-1021) + 4*TINY_SUB), &
               '2^-1021 + 3*2^-1074: tie to even (up)')
  end subroutine rounding_ties

  subroutine subnormals()
    type(exact_sum_t) :: acc
    integer :: k
    do k = 1, 1000
      call acc%add(TINY_SUB)
    end do
    call check(same(acc%value(), 1000*TINY_SUB), '1000 steps of 2^-1074')
    call check(same(sum_of([tiny(1.0_dp), -TINY_SUB]), tiny(1.0_dp) - TINY_SUB), &
               'tiny - 2^-1074: the largest subnormal')
    call check(same(sum_of([tiny(1.0_dp)/2, tiny(1.0_dp)/2]), tiny(1.0_dp)), 'two subnormals make tiny')
    call check(same(sum_of([TINY_SUB, -TINY_SUB]), 0.0_dp), '2^-1074 - 2^-1074 = +0')
    call check(same(sum_of([-3*TINY_SUB, TINY_SUB]), -2*TINY_SUB), 'negative subnormal')
    call check(same(sum_of([2.0_dp**(-1000), -2.0_dp**(-1000), 5*TINY_SUB]), 5*TINY_SUB), &
               '2^-1000 - 2^-1000 + 5*2^-1074')
  end subroutine subnormals

  !> Fisher-Yates with the test's stream.
  subroutine shuffle(order)
    integer, intent(inout) :: order(:)
    integer :: i, j, t
    do i = size(order), 2, -1
      j = 1 + int(rng%uniform()*i)
      j = min(j, i)
      t = order(i)
      order(i) = order(j)
      order(j) = t
    end do
  end subroutine shuffle

  !> The terms in a shuffled order, cut into n_groups random groups, each summed alone,
  !> the groups merged in another random order; and the same groups as integer words
  !> summed and handed to set_words (the MPI reduction's arithmetic). Both bitwise expected.
  subroutine groups_agree(x, expected, n_groups, what)
    real(dp), intent(in) :: x(:), expected
    integer, intent(in) :: n_groups
    character(len=*), intent(in) :: what
    type(exact_sum_t), allocatable :: part(:)
    type(exact_sum_t) :: total, from_words
    integer, allocatable :: order(:), group_order(:)
    integer(i8) :: words(EXACT_SUM_WORDS)
    integer :: i, g
    order = [(i, i=1, size(x))]
    call shuffle(order)
    allocate (part(n_groups))
    do i = 1, size(x)
      g = min(1 + int(rng%uniform()*n_groups), n_groups)
      call part(g)%add(x(order(i)))
    end do
    group_order = [(g, g=1, n_groups)]
    call shuffle(group_order)
    words = 0
    do g = 1, n_groups
      call total%merge(part(group_order(g)))
      words = words + part(g)%words()
    end do
    call from_words%set_words(words, n_groups)
    call check(same(total%value(), expected), what//': '//str(n_groups)//' groups merged in a random order')
    call check(same(from_words%value(), expected), what//': '//str(n_groups)//' groups summed as integer words')
  end subroutine groups_agree

  !> Terms (1 + u) 2^k, k in -20..20, random signs: all multiples of 2^-72 below 2^21, so
  !> 1000 of them sum exactly in real128 (103 < 113 bits); rounded once to double that is
  !> the reference.
  subroutine random_against_quad()
    integer, parameter :: N = 1000
    integer, parameter :: GROUPS(8) = [1, 2, 3, 4, 7, 8, 64, 1000]
    real(dp) :: x(N), plain
    real(real128) :: quad
    integer, allocatable :: order(:)
    integer :: i, trial
    logical :: ok
    do i = 1, N
      x(i) = scale(1.0_dp + rng%uniform(), int(rng%uniform()*41) - 20)
      if (rng%uniform() < 0.5_dp) x(i) = -x(i)
    end do
    quad = 0.0_real128
    plain = 0.0_dp
    do i = 1, N
      quad = quad + real(x(i), real128)
      plain = plain + x(i)
    end do
    call check(same(sum_of(x), real(quad, dp)), 'random terms: the exact real128 sum rounded once')
    write (output_unit, '(a,es10.2)') 'plain left-to-right sum differs from the exact one by ', &
      abs(plain - real(quad, dp))
    ok = .true.
    order = [(i, i=1, N)]
    do trial = 1, 10
      call shuffle(order)
      ok = ok .and. same(sum_of(x(order)), real(quad, dp))
    end do
    call check(ok, 'random terms: 10 shuffled orders bitwise the same')
    do trial = 1, 8
      call groups_agree(x, real(quad, dp), GROUPS(trial), 'random terms')
    end do
  end subroutine random_against_quad

  !> Any finite double (random bit patterns: subnormals to huge, both signs), each with its
  !> negative, plus three terms of known sum: the sum is theirs whatever the order.
  subroutine wide_range_cancelling()
    integer, parameter :: N = 2000
    real(dp) :: x(2*N + 3), expected
    integer(i8) :: bits
    integer :: i
    do i = 1, N
      do
        bits = rng%next_u64()
        if (ibits(bits, 52, 11) /= 2047) exit
      end do
      x(2*i - 1) = transfer(bits, 1.0_dp)
      x(2*i) = -x(2*i - 1)
    end do
    x(2*N + 1:) = [1.5_dp, 2.0_dp**(-1000), -0.25_dp]
    expected = 1.25_dp          ! 1.25 + 2^-1000 rounds to 1.25
    call check(same(sum_of(x), expected), 'wide-range pairs cancel: 1.5 + 2^-1000 - 0.25')
    call groups_agree(x, expected, 5, 'wide-range pairs')
    call groups_agree(x, expected, 97, 'wide-range pairs')
    x(2*N + 1:) = [TINY_SUB, 0.0_dp, 0.0_dp]
    call groups_agree(x, TINY_SUB, 13, 'wide-range pairs + 2^-1074')
  end subroutine wide_range_cancelling

  subroutine non_finite()
    type(exact_sum_t) :: a, b
    real(dp) :: nan
    nan = ieee_value(nan, ieee_quiet_nan)
    call check(ieee_is_nan(sum_of([1.0_dp, nan, 2.0_dp])), 'a NaN term: NaN')
    call check(same(sum_of([1.0_dp, inf, -huge(1.0_dp)]), inf), '+Inf and finite terms: +Inf')
    call check(same(sum_of([minus_inf, huge(1.0_dp)]), minus_inf), '-Inf and finite terms: -Inf')
    call check(same(sum_of([inf, inf]), inf), '+Inf + +Inf: +Inf')
    call check(ieee_is_nan(sum_of([inf, 1.0_dp, minus_inf])), '+Inf and -Inf: NaN (Inf - Inf)')
    call check(ieee_is_nan(sum_of([inf, nan])), '+Inf and NaN: NaN')
    call a%add(inf)
    call b%add(minus_inf)
    call b%add(3.0_dp)
    call check(same(b%value(), minus_inf), 'group of -Inf alone: -Inf')
    call a%merge(b)
    call check(ieee_is_nan(a%value()), '+Inf and -Inf from two merged groups: NaN')
    call a%reset()
    call a%add(2.0_dp)
    call check(same(a%value(), 2.0_dp), 'reset forgets the infinities and the sum')
  end subroutine non_finite

  !> Limbs take ~2^30 adds between carry propagations: 70 doublings by merging a copy
  !> (2^70 times the terms, far beyond that) stay exact, and sums beyond the double range
  !> come back when cancelled.
  subroutine headroom()
    type(exact_sum_t) :: a, copy, b
    integer :: k
    call a%add_array([1.0_dp, TINY_SUB])
    do k = 1, 70
      copy = a
      call a%merge(copy)
    end do
    call a%add(-2.0_dp**70)
    call check(same(a%value(), 2.0_dp**70*TINY_SUB), '(1 + 2^-1074) doubled 70 times minus 2^70: exact')
    call a%reset()
    call b%add(-huge(1.0_dp))
    call a%add(huge(1.0_dp))
    do k = 1, 40
      copy = a
      call a%merge(copy)
      copy = b
      call b%merge(copy)
    end do
    call check(same(a%value(), inf) .and. same(b%value(), minus_inf), '2^40 huge: +Inf, -2^40 huge: -Inf')
    call a%merge(b)
    call a%add(1.5_dp)
    call check(same(a%value(), 1.5_dp), '2^40 huge - 2^40 huge + 1.5 = 1.5')
  end subroutine headroom

  subroutine vector_form()
    type(exact_sum_t) :: v(3), s(3)
    real(dp) :: t(3)
    integer :: i, k
    logical :: ok
    do i = 1, 100
      t = [rng%symmetric(1.0e3_dp), rng%symmetric(1.0_dp), rng%symmetric(1.0e-3_dp)]
      call v%add(t)
      do k = 1, 3
        call s(k)%add(t(k))
      end do
    end do
    ok = .true.
    do k = 1, 3
      ok = ok .and. same(v(k)%value(), s(k)%value())
    end do
    call check(ok, 'elemental add over an array of accumulators: each its own sum')
    call check(all(v%value() == s%value()), 'elemental value()')
    call v(2:3)%merge(s(2:3))
    call check(same(v(2)%value(), sum_of([s(2)%value(), s(2)%value()])), 'elemental merge')
  end subroutine vector_form

  !> Cost per add in this build (Debug: runtime checks on); printed, not asserted.
  subroutine timing()
    integer, parameter :: N = 2000000
    real(dp), allocatable :: x(:)
    type(exact_sum_t) :: acc
    real(dp) :: t0, t1, t2, plain
    integer :: i
    allocate (x(N))
    do i = 1, N
      x(i) = rng%symmetric(1.0e3_dp)
    end do
    call cpu_time(t0)
    call acc%add_array(x)
    call cpu_time(t1)
    plain = 0.0_dp
    do i = 1, N
      plain = plain + x(i)
    end do
    call cpu_time(t2)
    write (output_unit, '(a,f8.2,a,f8.2,a)') 'timing: exact add ', (t1 - t0)/N*1.0e9_dp, &
      ' ns, plain add ', (t2 - t1)/N*1.0e9_dp, ' ns (this build''s flags)'
    call check(abs(acc%value() - plain) <= 1.0e-9_dp*N, 'timing loop: the sums agree to round-off')
  end subroutine timing

end program test_exact_sum
