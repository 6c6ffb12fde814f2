!> Small string helpers: number formatting for messages, case folding, paths.
module string_utils
  use kinds, only: dp, i8
  implicit none
  private
  public :: str, decimal_digits, lower, dirname, join_path, is_absolute_path, starts_with, ends_with, join_reals, name_index

  interface str
    module procedure str_int, str_int8, str_real, str_logical
  end interface str

contains

  !> The decimal digits of value, as '(i0)' writes them. Digit by digit, not by an internal
  !> write: the effective deck writes several integers per body, and gfortran's formatted
  !> I/O took 7% of a 100,000-sphere run's rank 0 there.
  pure function str_int(value) result(text)
    integer, intent(in) :: value
    character(len=:), allocatable :: text
    text = str_int8(int(value, i8))
  end function str_int

  pure function str_int8(value) result(text)
    integer(i8), intent(in) :: value
    character(len=:), allocatable :: text
    character(len=20) :: buffer    ! (19 digits of huge(0_i8), and the sign)
    integer :: first
    call decimal_digits(value, buffer, first)
    text = buffer(first:)
  end function str_int8

  !> value's decimal text, as '(i0)' writes it, right-aligned in buffer from buffer(first:)
  !> (20 characters hold any value): no heap string, for hot loops.
  pure subroutine decimal_digits(value, buffer, first)
    integer(i8), intent(in) :: value
    character(len=*), intent(out) :: buffer
    integer, intent(out) :: first
    integer(i8) :: v
    v = value
    first = len(buffer) + 1
    ! (a negative value digit by digit as a negative: -huge(0_i8) - 1 has no positive; mod
    ! then takes the sign of v)
    do
      first = first - 1
      buffer(first:first) = achar(iachar('0') + abs(int(mod(v, 10_i8))))
      v = v/10_i8
      if (v == 0) exit
    end do
    if (value < 0) then
      first = first - 1
      buffer(first:first) = '-'
    end if
  end subroutine decimal_digits

  !> Shortest round-trip-ish form for messages: 'g0' keeps all significant digits.
  pure function str_real(value, fmt) result(text)
    real(dp), intent(in) :: value
    character(len=*), intent(in), optional :: fmt
    character(len=:), allocatable :: text
    character(len=64) :: buffer
    if (present(fmt)) then
      write (buffer, fmt) value
    else
      write (buffer, '(g0)') value
    end if
    text = trim(adjustl(buffer))
  end function str_real

  pure function str_logical(value) result(text)
    logical, intent(in) :: value
    character(len=:), allocatable :: text
    if (value) then
      text = '.true.'
    else
      text = '.false.'
    end if
  end function str_logical

  pure function lower(text) result(folded)
    character(len=*), intent(in) :: text
    character(len=len(text)) :: folded
    integer :: i, c
    folded = text
    do i = 1, len(text)
      c = iachar(text(i:i))
      if (c >= iachar('A') .and. c <= iachar('Z')) folded(i:i) = achar(c + 32)
    end do
  end function lower

  pure logical function starts_with(text, prefix)
    character(len=*), intent(in) :: text, prefix
    starts_with = len(text) >= len(prefix)
    if (starts_with) starts_with = text(1:len(prefix)) == prefix
  end function starts_with

  pure logical function ends_with(text, suffix)
    character(len=*), intent(in) :: text, suffix
    ends_with = len(text) >= len(suffix)
    if (ends_with) ends_with = text(len(text) - len(suffix) + 1:) == suffix
  end function ends_with

  pure logical function is_absolute_path(path)
    character(len=*), intent(in) :: path
    is_absolute_path = .false.
    if (len_trim(path) > 0) is_absolute_path = path(1:1) == '/'
  end function is_absolute_path

  !> Folder part of a path ('.' when there is none).
  pure function dirname(path) result(dir)
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: dir
    integer :: slash
    slash = index(trim(path), '/', back=.true.)
    if (slash == 0) then
      dir = '.'
    else if (slash == 1) then
      dir = '/'
    else
      dir = path(1:slash - 1)
    end if
  end function dirname

  !> base/relative unless relative is absolute.
  pure function join_path(base, relative) result(path)
    character(len=*), intent(in) :: base, relative
    character(len=:), allocatable :: path
    if (is_absolute_path(relative) .or. len_trim(base) == 0 .or. trim(base) == '.') then
      path = trim(relative)
    else
      path = trim(base)//'/'//trim(relative)
    end if
  end function join_path

  !> Reals written with fmt and joined by separator: "1.0E+00, 2.0E+00, 3.0E+00".
  function join_reals(values, fmt, separator) result(text)
    real(dp), intent(in) :: values(:)
    character(len=*), intent(in) :: fmt, separator
    character(len=:), allocatable :: text
    integer :: i
    text = ''
    do i = 1, size(values)
      if (i > 1) text = text//separator
      text = text//str(values(i), fmt)
    end do
  end function join_reals

  !> Index of the first of names equal to name (blank-padded comparison), 0 if none: what
  !> findloc(names, name, dim=1) means. Not findloc itself: gfortran 12 declares its
  !> character findloc after the first call in a file, and when that call's value has
  !> deferred length (a group name from the scan) the length goes by address and nothing
  !> is ever found.
  pure integer function name_index(names, name) result(found)
    character(len=*), intent(in) :: names(:), name
    integer :: j
    found = 0
    do j = 1, size(names)
      if (names(j) == name) then
        found = j
        return
      end if
    end do
  end function name_index

end module string_utils
