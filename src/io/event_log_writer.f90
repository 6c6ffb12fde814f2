!> The event log (&output event_log = .true.): output/events.csv, one row per body whose
!> velocity an impact changed: the time, the body's global id, the linear impulse it got and
!> the angular impulse about its centre of mass (world frame). Written at the end of the run
!> (temporary file, then rename), every row in order of time, then of global id. The log is
!> for comparing runs (the local and the global event loop, two versions of the code): the
!> contact pass's impulses of resting contacts are not impacts and are not in it.
module event_log_writer
  use error_status, only: error_t, ERR_IO
  use file_system, only: rename_file, remove_file, stream_t, stream_open, stream_write, stream_close
  use sorting, only: sort_index_keys
  use kinds, only: dp, i8
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
    integer, parameter :: chunk_bytes = 65536
    type(stream_t) :: stream
    type(error_t) :: ignored
    character(len=:), allocatable :: chunk
    character(len=256) :: row
    integer :: k
    integer, allocatable :: order(:)
    integer(i8), allocatable :: keys(:, :)
    ! by time, then global id (the order of the bits of a non-negative double is its order)
    allocate (keys(2, n))
    do k = 1, n
      keys(:, k) = [transfer(rows(1, k), 1_i8), nint(rows(2, k), i8)]
    end do
    call sort_index_keys(keys, order)
    ! Through checked C stdio (file_system: gfortran's formatted writes do not report a full
    ! disk), in chunks of rows, to path.tmp renamed when complete.
    call stream_open(path//'.tmp', 'w', stream, err)
    call stream_write(stream, 'time [s],gid [1],impulse_x [N s],impulse_y [N s],impulse_z [N s],'// &
                      'angular_impulse_x [N m s],angular_impulse_y [N m s],angular_impulse_z [N m s]', err, line=.true.)
    chunk = ''
    do k = 1, n
      write (row, '(es25.17,",",i0,6(",",es25.17))') rows(1, order(k)), nint(rows(2, order(k)), i8), rows(3:8, order(k))
      chunk = chunk//trim(row)//new_line('a')
      if (len(chunk) > chunk_bytes .or. k == n) then
        call stream_write(stream, chunk, err)
        chunk = ''
      end if
    end do
    call stream_close(stream, err)
    if (err%failed()) then
      call remove_file(path//'.tmp', ignored)
      call err%prefix("the event log '"//path//"' is not written: ")
      return
    end if
    call rename_file(path//'.tmp', path, err)
  end subroutine write_event_log

end module event_log_writer
