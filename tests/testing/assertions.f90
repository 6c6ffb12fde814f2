!> The one small assertion module of the test suite (no framework): checks count passes and
!> failures, print a line for each failure, and test_finish prints the closing
!> "N passed, M failed" line and exits non-zero on any failure.
module assertions
  use, intrinsic :: iso_fortran_env, only: dp => real64, output_unit, error_unit
  use, intrinsic :: ieee_arithmetic, only: ieee_is_nan
  implicit none
  private
  public :: check, check_close, check_close_array, check_error, test_finish, test_data_path, &
            rel_diff

  integer, save :: n_passed = 0   ! test-program state: the only mutable module data allowed
  integer, save :: n_failed = 0

contains

  subroutine check(condition, what)
    logical, intent(in) :: condition
    character(len=*), intent(in) :: what
    if (condition) then
      n_passed = n_passed + 1
    else
      n_failed = n_failed + 1
      write (error_unit, '(a)') 'FAIL: '//what
    end if
  end subroutine check

  !> |actual - expected| <= atol + rtol*|expected|
  subroutine check_close(actual, expected, rtol, what, atol)
    real(dp), intent(in) :: actual, expected, rtol
    character(len=*), intent(in) :: what
    real(dp), intent(in), optional :: atol
    real(dp) :: a_tol
    a_tol = 0.0_dp
    if (present(atol)) a_tol = atol
    if (.not. ieee_is_nan(actual) .and. abs(actual - expected) <= a_tol + rtol*abs(expected)) then
      n_passed = n_passed + 1
    else
      n_failed = n_failed + 1
      write (error_unit, '(a,es24.16,a,es24.16,a,es10.2,a,es10.2)') 'FAIL: '//what//': got ', actual, &
        ' expected ', expected, ' rel.diff ', rel_diff(actual, expected), ' rtol ', rtol
    end if
  end subroutine check_close

  subroutine check_close_array(actual, expected, rtol, what, atol)
    real(dp), intent(in) :: actual(:), expected(:), rtol
    character(len=*), intent(in) :: what
    real(dp), intent(in), optional :: atol
    integer :: i
    real(dp) :: a_tol
    logical :: ok
    a_tol = 0.0_dp
    if (present(atol)) a_tol = atol
    ok = size(actual) == size(expected)
    if (ok) then
      do i = 1, size(actual)
        if (ieee_is_nan(actual(i)) .or. abs(actual(i) - expected(i)) > a_tol + rtol*abs(expected(i))) ok = .false.
      end do
    end if
    if (ok) then
      n_passed = n_passed + 1
    else
      n_failed = n_failed + 1
      write (error_unit, '(a)') 'FAIL: '//what
      write (error_unit, '(a,*(es24.16))') '   got      ', actual
      write (error_unit, '(a,*(es24.16))') '   expected ', expected
    end if
  end subroutine check_close_array

  !> A call that should have failed: code /= 0 and the message contains every fragment.
  subroutine check_error(code, message, fragments, what)
    integer, intent(in) :: code
    character(len=*), intent(in) :: message
    character(len=*), intent(in) :: fragments(:)
    character(len=*), intent(in) :: what
    integer :: i
    logical :: ok
    ok = code /= 0
    do i = 1, size(fragments)
      if (index(message, trim(fragments(i))) == 0) ok = .false.
    end do
    if (ok) then
      n_passed = n_passed + 1
    else
      n_failed = n_failed + 1
      write (error_unit, '(a,i0,a)') 'FAIL: '//what//' (code ', code, ', message "'//trim(message)//'")'
      write (error_unit, '(a,*(a,:,", "))') '   expected fragments: ', (trim(fragments(i)), i=1, size(fragments))
    end if
  end subroutine check_error

  pure real(dp) function rel_diff(a, b)
    real(dp), intent(in) :: a, b
    rel_diff = abs(a - b)/max(abs(b), tiny(1.0_dp))
  end function rel_diff

  !> Path of a file in tests/data (RICOCHET_TEST_DATA is set by CTest).
  function test_data_path(name) result(path)
    character(len=*), intent(in) :: name
    character(len=:), allocatable :: path
    character(len=4096) :: dir
    integer :: length, status
    call get_environment_variable('RICOCHET_TEST_DATA', dir, length, status)
    if (status /= 0) dir = '../../../../tests/data'
    path = trim(dir)//'/'//name
  end function test_data_path

  subroutine test_finish()
    write (output_unit, '(i0,a,i0,a)') n_passed, ' passed, ', n_failed, ' failed'
    if (n_failed > 0) error stop 1
    ! A test that checked nothing cannot fail: that is a defect of the test.
    if (n_passed == 0) error stop 'no checks were made'
  end subroutine test_finish

end module assertions
