!> Exact, order-independent sums of real(dp) values (a "small superaccumulator", Neal 2015;
!> Collange, Defour, Graillat and Iakymchuk 2015), so that a global total is bitwise the
!> same however the terms are split over ranks and in whatever order they are added.
!>
!> Every finite double is an integer multiple of 2^-1074 (the smallest subnormal), of at
!> most 2098 bits. The sum is kept as that integer, in limbs of 32 bits: limb k (0..65)
!> holds the bits of weight 2^(32k - 1074); the top limb (66) holds everything above, with
!> the sign. Limbs are int64, so between carry propagations (normalise) each can take some
!> 2^30 further adds of at most 2^32 - 1 each; the accumulator counts them (load) and
!> propagates carries before the headroom runs out. Adding a value is three integer
!> additions; value() rounds the exact integer to the nearest double, ties to even.
!>
!> Normalised limbs are in [0, 2^32) (the top one signed, of magnitude about
!> sum/2^1038, in practice 0 or -1): the integer sum of fewer than 2^31 normalised word
!> arrays cannot overflow int64, so words() of any number of MPI ranks (sizes are default
!> integers) can be summed with an integer reduction (MPI_SUM on MPI_INTEGER8, which is
!> associative and commutative) and handed back through set_words.
!>
!> Non-finite terms are counted, not added (the last three words): value() is NaN if a NaN
!> was added or both +Inf and -Inf were (IEEE: Inf - Inf is NaN), else +Inf or -Inf if
!> only that infinity was, else the rounded exact sum of the finite terms. That exact sum
!> is never lost to overflow on the way (1e308 + 1e308 - 1e308 is 1e308, in any order);
!> if the sum itself is beyond the double range, value() is the infinity of its sign, as
!> rounding to nearest does.
module exact_sum
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan, ieee_positive_inf, &
                                           ieee_negative_inf
  use kinds, only: dp, i8
  implicit none
  private
  public :: exact_sum_t, EXACT_SUM_WORDS, EXACT_SUM_MAX_TERMS

  integer, parameter :: LIMB_BITS = 32
  integer, parameter :: TOP = 66                  !< limbs 0..TOP; bits >= 32*TOP in limb TOP
  integer, parameter :: I_NAN = TOP + 1, I_POS_INF = TOP + 2, I_NEG_INF = TOP + 3
  !> words of an accumulator as words() gives them: the limbs, then the NaN, +Inf and
  !> -Inf counts
  integer, parameter :: EXACT_SUM_WORDS = TOP + 4
  !> at most this many normalised word arrays may be summed as integers (set_words' n_terms)
  integer(i8), parameter :: EXACT_SUM_MAX_TERMS = 2_i8**31 - 1
  integer(i8), parameter :: MASK32 = 2_i8**32 - 1
  !> a limb's magnitude stays below (load + 1)*2^32; carries go before load passes this,
  !> so that even two accumulators at the limit merge without overflow (2^31 * 2^32 < 2^63)
  integer(i8), parameter :: MAX_LOAD = 2_i8**29

  type :: exact_sum_t
    private
    integer(i8) :: word(0:EXACT_SUM_WORDS - 1) = 0_i8
    integer(i8) :: load = 0_i8    !< adds (of < 2^32 per limb) since the limbs were normalised
  contains
    procedure :: add => exact_add
    procedure :: add_array => exact_add_array
    procedure :: merge => exact_merge
    procedure :: value => exact_value
    procedure :: reset => exact_reset
    procedure :: words => exact_words
    procedure :: set_words => exact_set_words
  end type exact_sum_t

contains

  !> Adds x exactly. Elemental, so an array of accumulators (one per total) takes an array
  !> of terms in one call: call totals(5:7)%add(m*v).
  elemental subroutine exact_add(self, x)
    class(exact_sum_t), intent(inout) :: self
    real(dp), intent(in) :: x
    integer(i8) :: bits, mantissa, rest, negate
    integer :: biased, shift, k, r
    ! the bit pattern, not arithmetic: no floating-point operation (and no trap) on NaN
    bits = transfer(x, 0_i8)
    biased = int(ibits(bits, 52, 11))
    mantissa = ibits(bits, 0, 52)
    if (biased == 2047) then
      if (mantissa /= 0_i8) then
        self%word(I_NAN) = self%word(I_NAN) + 1
      else if (bits < 0_i8) then
        self%word(I_NEG_INF) = self%word(I_NEG_INF) + 1
      else
        self%word(I_POS_INF) = self%word(I_POS_INF) + 1
      end if
      return
    end if
    if (mantissa == 0_i8 .and. biased == 0) return          ! +0 and -0 add nothing
    if (self%load >= MAX_LOAD) call normalise(self)
    ! x = mantissa * 2^(shift - 1074) with mantissa < 2^53; subnormals have shift 0
    if (biased == 0) then
      shift = 0
    else
      mantissa = ior(mantissa, 2_i8**52)
      shift = biased - 1
    end if
    k = shift/LIMB_BITS
    r = mod(shift, LIMB_BITS)
    ! mantissa * 2^r (up to 85 bits) as three pieces below 2^32, added to limbs k..k+2
    rest = ishft(mantissa, -(LIMB_BITS - r))
    mantissa = ishft(iand(mantissa, ishft(1_i8, LIMB_BITS - r) - 1), r)
    ! the sign without a branch (random signs would mispredict half the time): negate is 0
    ! or -1 (all ones), and ieor(p, negate) - negate is p or -p
    negate = shifta(bits, 63)
    self%word(k) = self%word(k) + (ieor(mantissa, negate) - negate)
    self%word(k + 1) = self%word(k + 1) + (ieor(iand(rest, MASK32), negate) - negate)
    self%word(k + 2) = self%word(k + 2) + (ieor(ishft(rest, -LIMB_BITS), negate) - negate)
    self%load = self%load + 1
  end subroutine exact_add

  pure subroutine exact_add_array(self, x)
    class(exact_sum_t), intent(inout) :: self
    real(dp), intent(in) :: x(:)
    integer :: i
    do i = 1, size(x)
      call self%add(x(i))
    end do
  end subroutine exact_add_array

  !> self = self + other, exactly (the sum of two partial sums: groups merge in any order).
  elemental subroutine exact_merge(self, other)
    class(exact_sum_t), intent(inout) :: self
    type(exact_sum_t), intent(in) :: other
    if (self%load + other%load >= 2*MAX_LOAD) call normalise(self)
    self%word = self%word + other%word
    self%load = self%load + other%load
    if (self%load > MAX_LOAD) call normalise(self)
  end subroutine exact_merge

  elemental subroutine exact_reset(self)
    class(exact_sum_t), intent(inout) :: self
    self%word = 0_i8
    self%load = 0_i8
  end subroutine exact_reset

  !> The words (limbs normalised, then the NaN, +Inf, -Inf counts) for an integer sum
  !> over ranks: sum fewer than 2^31 of them and give the result to set_words.
  pure function exact_words(self) result(w)
    class(exact_sum_t), intent(in) :: self
    integer(i8) :: w(EXACT_SUM_WORDS)
    type(exact_sum_t) :: copy
    copy%word = self%word
    copy%load = self%load
    call normalise(copy)
    w = copy%word
  end function exact_words

  !> self becomes the accumulator whose words are w, the integer sum of n_terms arrays
  !> from words() (n_terms <= EXACT_SUM_MAX_TERMS: each limb is then below n_terms*2^32).
  pure subroutine exact_set_words(self, w, n_terms)
    class(exact_sum_t), intent(inout) :: self
    integer(i8), intent(in) :: w(EXACT_SUM_WORDS)
    integer, intent(in) :: n_terms
    self%word = w
    self%load = max(int(n_terms, i8), 1_i8)
    call normalise(self)
  end subroutine exact_set_words

  !> Carry propagation: limbs 0..TOP-1 into [0, 2^32), the rest (signed) into the top.
  !> iand keeps the low 32 bits of the two's complement limb, shifta the floor of limb/2^32.
  elemental subroutine normalise(self)
    type(exact_sum_t), intent(inout) :: self
    integer(i8) :: carry
    integer :: k
    carry = 0_i8
    do k = 0, TOP - 1
      self%word(k) = self%word(k) + carry
      carry = shifta(self%word(k), LIMB_BITS)
      self%word(k) = iand(self%word(k), MASK32)
    end do
    self%word(TOP) = self%word(TOP) + carry
    self%load = 0_i8
  end subroutine normalise

  !> The exact sum rounded to the nearest double, ties to even (see the module header for
  !> NaN and infinities). Does not change the accumulator.
  elemental real(dp) function exact_value(self) result(v)
    class(exact_sum_t), intent(in) :: self
    type(exact_sum_t) :: a
    integer(i8) :: mantissa
    integer :: k, high, lead, first, exponent
    logical :: negative, round_bit, sticky
    if (self%word(I_NAN) > 0 .or. (self%word(I_POS_INF) > 0 .and. self%word(I_NEG_INF) > 0)) then
      v = ieee_value(v, ieee_quiet_nan)
      return
    else if (self%word(I_POS_INF) > 0) then
      v = ieee_value(v, ieee_positive_inf)
      return
    else if (self%word(I_NEG_INF) > 0) then
      v = ieee_value(v, ieee_negative_inf)
      return
    end if
    a%word = self%word
    a%load = self%load
    call normalise(a)
    ! lower limbs are non-negative, so the sign is the top limb's; take the magnitude
    negative = a%word(TOP) < 0_i8
    if (negative) then
      a%word(0:TOP) = -a%word(0:TOP)
      call normalise(a)
    end if
    high = -1
    do k = TOP, 0, -1
      if (a%word(k) /= 0_i8) then
        high = k
        exit
      end if
    end do
    if (high < 0) then
      v = 0.0_dp
      return
    end if
    ! lead: the position of the leading bit of the integer (units of 2^-1074)
    lead = LIMB_BITS*high + 63 - leadz(a%word(high))
    if (lead <= 52) then
      ! below 2^53 units (2^-1021): exactly representable (subnormals included)
      v = scale(real(a%word(0) + ishft(a%word(1), LIMB_BITS), dp), -1074)
    else
      first = lead - 52
      mantissa = 0_i8
      do k = lead, first, -1
        mantissa = ior(ishft(mantissa, 1), merge(1_i8, 0_i8, bit_at(a, k)))
      end do
      round_bit = bit_at(a, first - 1)
      sticky = any_bit_below(a, first - 1)
      if (round_bit .and. (sticky .or. btest(mantissa, 0))) mantissa = mantissa + 1
      exponent = first - 1074
      if (mantissa == 2_i8**53) then
        mantissa = 2_i8**52
        exponent = exponent + 1
      end if
      ! a 53-bit mantissa times 2^971 is the largest finite double
      if (exponent > 971) then
        v = ieee_value(v, ieee_positive_inf)
      else
        v = scale(real(mantissa, dp), exponent)
      end if
    end if
    if (negative) v = -v
  end function exact_value

  !> Bit j (units of 2^-1074) of a normalised, non-negative accumulator.
  pure logical function bit_at(a, j)
    type(exact_sum_t), intent(in) :: a
    integer, intent(in) :: j
    integer :: k
    k = j/LIMB_BITS
    if (k >= TOP) then
      bit_at = j - LIMB_BITS*TOP < 64 .and. btest(a%word(TOP), min(j - LIMB_BITS*TOP, 63))
    else
      bit_at = btest(a%word(k), mod(j, LIMB_BITS))
    end if
  end function bit_at

  !> Whether any bit below bit j is set (the sticky bit of rounding), limb by limb.
  pure logical function any_bit_below(a, j)
    type(exact_sum_t), intent(in) :: a
    integer, intent(in) :: j
    integer :: k
    k = min(j/LIMB_BITS, TOP)
    any_bit_below = any(a%word(0:k - 1) /= 0_i8)
    if (.not. any_bit_below .and. j - LIMB_BITS*k > 0) &
      any_bit_below = iand(a%word(k), ishft(1_i8, min(j - LIMB_BITS*k, 62)) - 1) /= 0_i8
  end function any_bit_below

end module exact_sum
