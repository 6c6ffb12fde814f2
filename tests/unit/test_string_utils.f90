!> string_utils: str of integers (default kind and 64-bit) gives exactly what '(i0)' writes,
!> at zero, one digit, every power of ten and its neighbours, both extremes of both kinds
!> and random values; compared as text, so any digit, sign or length wrong fails.
program test_string_utils
  use kinds, only: i8
  use string_utils, only: str
  use random_stream, only: random_stream_t
  use assertions
  implicit none
  integer(i8) :: p, v
  integer :: k, m
  type(random_stream_t) :: rng

  call same_as_i0(0_i8)
  call same_as_i0(huge(0_i8))
  call same_as_i0(-huge(0_i8))
  call same_as_i0(-huge(0_i8) - 1_i8)
  call same_as_i0_default(huge(0))
  call same_as_i0_default(-huge(0))
  call same_as_i0_default(-huge(0) - 1)
  call same_as_i0_default(0)
  call same_as_i0_default(-7)
  p = 1
  do k = 0, 18
    do m = -1, 1
      call same_as_i0(p + m)
      call same_as_i0(-(p + m))
    end do
    p = p*10
  end do
  call rng%init(20261207)
  do k = 1, 2000
    v = int((rng%uniform() - 0.5d0)*2.0d0**62, i8)*int(1 + 3*rng%uniform(), i8)
    call same_as_i0(v)
    call same_as_i0_default(int(mod(v, int(huge(0), i8))))
  end do
  call test_finish()

contains

  subroutine same_as_i0(value)
    integer(i8), intent(in) :: value
    character(len=32) :: expected
    write (expected, '(i0)') value
    call check(str(value) == trim(expected), 'str(int64 '//trim(expected)//') gave '''//str(value)//'''')
  end subroutine same_as_i0

  subroutine same_as_i0_default(value)
    integer, intent(in) :: value
    character(len=32) :: expected
    write (expected, '(i0)') value
    call check(str(value) == trim(expected), 'str(int '//trim(expected)//') gave '''//str(value)//'''')
  end subroutine same_as_i0_default

end program test_string_utils
