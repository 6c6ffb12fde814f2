!> Error status propagated from library code to the driver: library code never stops,
!> it fills an error_t and returns; the driver prints one line and exits non-zero.
module error_status
  implicit none
  private
  public :: error_t
  public :: ERR_NONE, ERR_INPUT, ERR_MESH, ERR_IO, ERR_NUMERIC, ERR_CHECKPOINT, ERR_PARALLEL, &
            ERR_INTERNAL

  integer, parameter :: ERR_NONE = 0
  integer, parameter :: ERR_INPUT = 1        !< bad deck or command line
  integer, parameter :: ERR_MESH = 2         !< unreadable, open, non-manifold or degenerate mesh
  integer, parameter :: ERR_IO = 3           !< file system or HDF5 failure
  integer, parameter :: ERR_NUMERIC = 4      !< non-convergence, NaN, LAPACK failure
  integer, parameter :: ERR_CHECKPOINT = 5   !< truncated, foreign or mismatched checkpoint
  integer, parameter :: ERR_PARALLEL = 6     !< MPI failure or ranks that disagree
  integer, parameter :: ERR_INTERNAL = 7     !< a broken invariant: a bug in ricochet

  type :: error_t
    integer :: code = ERR_NONE
    character(len=:), allocatable :: message
  contains
    procedure :: set => error_set
    procedure :: failed => error_failed
    procedure :: ok => error_ok
    procedure :: prefix => error_prefix
    procedure :: clear => error_clear
  end type error_t

contains

  subroutine error_set(self, code, message)
    class(error_t), intent(inout) :: self
    integer, intent(in) :: code
    character(len=*), intent(in) :: message
    self%code = code
    self%message = message
  end subroutine error_set

  !> Adds context in front of an error raised deeper down ("mesh 'x.obj': " // message).
  subroutine error_prefix(self, context)
    class(error_t), intent(inout) :: self
    character(len=*), intent(in) :: context
    if (self%code == ERR_NONE) return
    if (allocated(self%message)) then
      self%message = context//self%message
    else
      self%message = context
    end if
  end subroutine error_prefix

  subroutine error_clear(self)
    class(error_t), intent(inout) :: self
    self%code = ERR_NONE
    if (allocated(self%message)) deallocate (self%message)
  end subroutine error_clear

  pure logical function error_failed(self)
    class(error_t), intent(in) :: self
    error_failed = self%code /= ERR_NONE
  end function error_failed

  pure logical function error_ok(self)
    class(error_t), intent(in) :: self
    error_ok = self%code == ERR_NONE
  end function error_ok

end module error_status
