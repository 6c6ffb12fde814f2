!> The event log (&output event_log = .true.): output/events.csv, one row per body whose
!> velocity an impact changed: the time, the body's global id, the linear impulse it got and
!> the angular impulse about its centre of mass (world frame). Written at the end of the run
!> (temporary file, then rename), every row in order of time, then of global id. The log is
!> for comparing runs (the local and the global event loop, two versions of the code): the
!> contact pass's impulses of resting contacts are not impacts and are not in it.
module event_log_writer
  use kinds, only: dp
  use error_status, only: error_t, ERR_IO
  use file_system, only: rename_file
  use sorting, only: sort_index_keys
  use kinds, only: i8
  implicit none
  private
  public :: write_event_log

contains

  !> rows(8, n): time [s], global id, impulse (3) [N s], angular impulse (3) [N m s].
  subroutine write_event_log(path, rows, n, err)
    character(len=*), intent(in) :: path
    real(dp), intent(in) :: rows(:, :)
    integer, intent(in) :: n
    type(error_t), intent(inout) :: err
    integer :: unit, ios, k
    integer, allocatable :: order(:)
    integer(i8), allocatable :: keys(:, :)
    character(len=512) :: msg
    ! by time, then global id (the order of the bits of a non-negative double is its order)
    allocate (keys(2, n))
    do k = 1, n
      keys(:, k) = [transfer(rows(1, k), 1_i8), nint(rows(2, k), i8)]
    end do
    call sort_index_keys(keys, order)
    open (newunit=unit, file=path//'.tmp', status='replace', action='write', iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call err%set(ERR_IO, "cannot write the event log '"//path//".tmp': "//trim(msg))
      return
    end if
    write (unit, '(a)') 'time [s],gid [1],impulse_x [N s],impulse_y [N s],impulse_z [N s],'// &
      'angular_impulse_x [N m s],angular_impulse_y [N m s],angular_impulse_z [N m s]'
    do k = 1, n
      write (unit, '(es25.17,",",i0,6(",",es25.17))', iostat=ios) rows(1, order(k)), nint(rows(2, order(k)), i8), &
        rows(3:8, order(k))
      if (ios /= 0) exit
    end do
    close (unit)
    if (ios /= 0) then
      call err%set(ERR_IO, "cannot write the event log '"//path//".tmp'")
      return
    end if
    call rename_file(path//'.tmp', path, err)
  end subroutine write_event_log

end module event_log_writer
