!> Requests to stop a run early and cleanly: SIGTERM or SIGINT (what a batch scheduler sends
!> before the wall limit, or Ctrl-C), through the C handlers of stop_signals.c, which only
!> record the signal. The run loops ask at points where every rank agrees (docs/output.md).
module stop_request
  use, intrinsic :: iso_c_binding, only: c_int
  use error_status, only: error_t, ERR_INTERNAL
  implicit none
  private
  public :: install_stop_handlers, stop_signal_received, signal_name, exit_now

  integer, parameter, public :: SIGNAL_INT = 2    !< POSIX SIGINT (Ctrl-C)
  integer, parameter, public :: SIGNAL_TERM = 15  !< POSIX SIGTERM (schedulers, kill)

  interface
    integer(c_int) function c_install_stop_handlers() bind(C, name='ricochet_install_stop_handlers')
      import :: c_int
    end function c_install_stop_handlers
    integer(c_int) function c_stop_signal() bind(C, name='ricochet_stop_signal')
      import :: c_int
    end function c_stop_signal
    subroutine c_exit_now(code) bind(C, name='ricochet_exit_now')
      import :: c_int
      integer(c_int), value :: code
    end subroutine c_exit_now
  end interface

contains

  !> Installs the handlers (once, before the run; also makes SIGXFSZ ignored, so a file-size
  !> limit is a write error that names the file).
  subroutine install_stop_handlers(err)
    type(error_t), intent(inout) :: err
    if (c_install_stop_handlers() /= 0) call err%set(ERR_INTERNAL, 'cannot install the SIGTERM/SIGINT handlers')
  end subroutine install_stop_handlers

  !> The stop signal this process received (SIGNAL_TERM, SIGNAL_INT), or 0. Local: the
  !> loops combine it over ranks themselves.
  integer function stop_signal_received()
    stop_signal_received = int(c_stop_signal())
  end function stop_signal_received

  !> Ends the process with `code` without any clean-up (no MPI_Finalize, no HDF5 shutdown):
  !> the driver's way out after an I/O error, when HDF5's shutdown may crash (stop_signals.c).
  subroutine exit_now(code)
    integer, intent(in) :: code
    call c_exit_now(int(code, c_int))
  end subroutine exit_now

  pure function signal_name(number) result(name)
    integer, intent(in) :: number
    character(len=:), allocatable :: name
    select case (number)
    case (SIGNAL_INT)
      name = 'SIGINT'
    case (SIGNAL_TERM)
      name = 'SIGTERM'
    case default
      name = 'signal'
    end select
  end function signal_name

end module stop_request
