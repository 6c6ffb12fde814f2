!> namelist_source's real_text, the deck text of a real (effective decks, checkpoints): its
!> fast path (one write of 21 digits, candidates rounded from it, C's strtod) gives exactly
!> the text of the reference path (one formatted write and one READ per number of digits) on
!> random doubles over the whole exponent range, on short decimals (deck values: 0.05,
!> 9.81), on exact ties of the decimal rounding (0.125, 2^-k: the case the fast path hands
!> to the reference), powers of two (an uneven rounding interval), subnormals and the
!> largest doubles, integral values (their own fast path, below 2^53); and every text reads back as the value, bit for bit. A fast path that
!> rounded a tie the wrong way, dropped a carry (9.999... -> 10.0) or lost a digit fails
!> here with the value in hex. Timed too (a line, not a check): the fast path is what keeps
!> the effective deck of 10^5 bodies out of every checkpoint's wall time.
program test_deck_text
  use kinds, only: dp, i8
  use string_utils, only: str
  use random_stream, only: random_stream_t
  use namelist_source, only: real_text
  use assertions
  implicit none
  type(random_stream_t) :: rng
  integer :: k, e, n_mismatch, n_bad_read
  real(dp) :: x, t0, t1, t2
  integer(i8) :: bits
  logical :: empty

  call rng%init(20261206)
  n_mismatch = 0
  n_bad_read = 0
  ! known texts
  call check(real_text(0.05_dp) == '0.05', 'real_text(0.05) = 0.05')
  call check(real_text(9.81_dp) == '9.81', 'real_text(9.81) = 9.81')
  call check(real_text(1000.0_dp) == '1000.0', 'real_text(1000) = 1000.0')
  call check(real_text(1.0e-14_dp) == '1.0e-14', 'real_text(1e-14) = 1.0e-14')
  call check(real_text(-2.5e8_dp) == '-2.5e8', 'real_text(-2.5e8) = -2.5e8')
  call check(real_text(0.1_dp + 0.2_dp) == '0.30000000000000004', 'real_text(0.1 + 0.2) has 17 digits')
  call check(real_text(0.0_dp) == '0.0' .and. real_text(-0.0_dp) == '-0.0', 'signed zeros')
  ! random bit patterns over the whole range, uniform doubles, short decimals, ties
  do k = 1, 20000
    bits = int(rng%uniform()*2.0_dp**31, i8)*2_i8**32 + int(rng%uniform()*2.0_dp**32, i8)
    ! (NaN and Inf patterns skipped as bits: comparing a signalling NaN traps in the Debug
    ! build, and real_text writes them as g0 anyway)
    if (iand(shiftr(bits, 52), 2047_i8) /= 2047_i8) then
      x = transfer(bits, 1.0_dp)
      call compare(x)
    end if
    call compare(rng%symmetric(3.0_dp))
    call compare(real(int(rng%uniform()*1.0e4_dp), dp)/10.0_dp**int(rng%uniform()*8.0_dp))
    call compare(real(int(rng%uniform()*1.0e3_dp) + 1, dp)*2.0_dp**(-int(rng%uniform()*30.0_dp)))
  end do
  ! decimal ties (0.125, 0.0625, ...: 5 then zeros after some digit), powers of two and
  ! their neighbours, carries (9.5, 0.9999999999999999), the ends of the range
  do e = -1074, 1023
    x = scale(1.0_dp, e)
    call compare(x)
    call compare(nearest(x, 1.0_dp))
    if (e > -1074) call compare(nearest(x, -1.0_dp))
  end do
  ! integral values (the fast path of deck defaults: -1, 1, 1000), up to 2^53 and past it
  do k = 1, 20000
    call compare(real(int(rng%uniform()*1.0e6_dp), dp) - 5.0e5_dp)
    call compare(aint(rng%uniform()*2.0_dp**53))
    call compare(aint(rng%uniform()*10.0_dp**int(rng%uniform()*16.0_dp)))
  end do
  call compare(-1.0_dp)
  call compare(2.0_dp**53 - 1.0_dp)
  call compare(2.0_dp**53)
  call compare(2.0_dp**53 + 2.0_dp)
  call compare(1.0e15_dp)
  call compare(123456789012345.0_dp)
  call compare(9.5_dp)
  call compare(nearest(1.0_dp, -1.0_dp))
  call compare(nearest(10.0_dp, -1.0_dp))
  call compare(huge(1.0_dp))
  call compare(tiny(1.0_dp))
  call compare(nearest(huge(1.0_dp), -1.0_dp))
  call check(n_mismatch == 0, 'fast and reference texts equal ('//str(n_mismatch)//' differ)')
  call check(n_bad_read == 0, 'every text reads back bit for bit ('//str(n_bad_read)//' do not)')
  ! cost of each path on jittered positions (most deck reals of a large scene)
  call cpu_time(t0)
  do k = 1, 20000
    empty = real_text(1.0_dp + rng%symmetric(0.5_dp)) == ''
  end do
  call cpu_time(t1)
  do k = 1, 20000
    empty = real_text(1.0_dp + rng%symmetric(0.5_dp), by_io=.true.) == ''
  end do
  call cpu_time(t2)
  write (*, '(a,f8.3,a,f8.3,a)') 'real_text per jittered value: fast ', (t1 - t0)/20000.0_dp*1.0e6_dp, &
    ' us, reference ', (t2 - t1)/20000.0_dp*1.0e6_dp, ' us'
  call test_finish()

contains

  subroutine compare(value)
    real(dp), intent(in) :: value
    character(len=:), allocatable :: fast, reference
    real(dp) :: back
    integer :: ios
    fast = real_text(value)
    reference = real_text(value, by_io=.true.)
    if (fast /= reference) then
      n_mismatch = n_mismatch + 1
      if (n_mismatch <= 5) write (*, '(a,z16.16,4a)') 'differ at ', value, ': fast ', fast, ', reference ', reference
    end if
    read (fast, *, iostat=ios) back
    if (ios /= 0 .or. transfer(back, 1_i8) /= transfer(value, 1_i8)) then
      n_bad_read = n_bad_read + 1
      if (n_bad_read <= 5) write (*, '(a,z16.16,2a)') 'does not read back: ', value, ' as ', fast
    end if
  end subroutine compare


end program test_deck_text
