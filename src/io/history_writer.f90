!> The history time series (docs/output.md): one CSV row per record, written by rank 0 as
!> the run goes and flushed after every row, so a run that stops early keeps every row
!> written so far. Plain text on purpose: readable by any tool while the run is going.
!>
!> Columns (header line "name [unit],..."): time, dt, steps, kinetic_translational,
!> kinetic_rotational, potential, energy_total, momentum_{x,y,z}, angular_momentum_{x,y,z},
!> wall_time, events, contacts, advancement_iterations, min_separation, asleep. Reals are
!> written with 17 significant digits (es24.16e3), which round-trips
!> every double exactly.
module history_writer
  use kinds, only: dp, i8
  use error_status, only: error_t, ERR_IO, ERR_INTERNAL
  use string_utils, only: dirname
  use parallel_env, only: parallel_t
  use file_system, only: make_directory, rename_file, remove_file, file_exists, stream_t, stream_open, &
                         stream_write, stream_close
  implicit none
  private
  public :: history_record_t, history_writer_t, history_fresh_start, history_header

  !> restart_time for a run that starts afresh: no earlier row is kept.
  real(dp), parameter :: history_fresh_start = -huge(1.0_dp)

  !> The header line: column names with units. Rows written by history_writer_t%write have
  !> exactly these columns, in this order.
  character(len=*), parameter :: history_header = &
    'time [s],dt [s],steps [1],kinetic_translational [J],kinetic_rotational [J],potential [J],'// &
    'energy_total [J],momentum_x [kg m/s],momentum_y [kg m/s],momentum_z [kg m/s],'// &
    'angular_momentum_x [kg m^2/s],angular_momentum_y [kg m^2/s],angular_momentum_z [kg m^2/s],'// &
    'wall_time [s],events [1],contacts [1],advancement_iterations [1],min_separation [m],asleep [1]'
  integer, parameter :: line_length = 16384
  character(len=*), parameter :: row_format = &
    '(2(es24.16e3,","),i0,",",11(es24.16e3,","),3(i0,","),es24.16e3,",",i0)'

  !> One row: global values (already reduced over ranks).
  type :: history_record_t
    real(dp) :: time = 0.0_dp                    !< simulated time [s]
    real(dp) :: dt = 0.0_dp                      !< last step size [s]
    integer(i8) :: steps = 0                     !< steps taken so far
    real(dp) :: kinetic_translational = 0.0_dp   !< [J]
    real(dp) :: kinetic_rotational = 0.0_dp      !< [J]
    real(dp) :: potential = 0.0_dp               !< [J]
    real(dp) :: momentum(3) = 0.0_dp             !< total linear momentum [kg m/s]
    real(dp) :: angular_momentum(3) = 0.0_dp     !< of the free bodies about their centre of mass [kg m^2/s]
    real(dp) :: wall_time = 0.0_dp               !< since the start of the first run [s]
    integer(i8) :: events = 0                    !< steps that ended at a contact, so far
    integer(i8) :: contacts = 0                  !< contact points handed to the impulse solver, so far
    integer(i8) :: advancement_iterations = 0    !< closest-point queries in time of contact, so far
    real(dp) :: min_separation = huge(1.0_dp)    !< smallest gap between bodies seen so far [m]
    integer :: asleep = 0                        !< bodies asleep at this time
  end type history_record_t

  type :: history_writer_t
    character(len=:), allocatable :: path
    !> C stdio, not a Fortran unit: gfortran does not report a row lost to a full disk
    type(stream_t) :: stream
    logical :: is_open = .false.                  !< only ever on rank 0
  contains
    procedure :: init => history_init
    procedure :: write => history_write
    procedure :: free => history_free
  end type history_writer_t

contains

  !> Opens path for writing (collective; rank 0 writes). Rows with time <= restart_time
  !> already in the file are kept (a restart continues the series); later rows, rows cut
  !> short by a crash, and everything for history_fresh_start, are dropped. The trimmed file
  !> replaces the old one atomically (temporary file, then rename).
  subroutine history_init(self, par, path, restart_time, err)
    class(history_writer_t), intent(inout) :: self
    type(parallel_t), intent(in) :: par
    character(len=*), intent(in) :: path
    real(dp), intent(in) :: restart_time
    type(error_t), intent(inout) :: err
    call self%free()
    self%path = trim(path)
    if (par%is_root()) call init_on_root(self, restart_time, err)
    call agree(par, err, "history file '"//self%path//"': failed on rank 0")
  end subroutine history_init

  subroutine init_on_root(self, restart_time, err)
    type(history_writer_t), intent(inout) :: self
    real(dp), intent(in) :: restart_time
    type(error_t), intent(inout) :: err
    character(len=line_length) :: line
    character(len=:), allocatable :: temporary
    type(stream_t) :: out
    type(error_t) :: ignored
    integer :: in_unit, status, n_columns
    real(dp) :: row_time
    logical :: first

    call make_directory(dirname(self%path), err)
    if (err%failed()) return
    temporary = self%path//'.tmp'
    call stream_open(temporary, 'w', out, err)
    call stream_write(out, history_header, err, line=.true.)
    if (err%failed()) then
      call stream_close(out, err)
      call remove_file(temporary, ignored)
      return
    end if
    n_columns = count_columns(history_header)

    if (restart_time > history_fresh_start .and. file_exists(self%path)) then
      open (newunit=in_unit, file=self%path, status='old', action='read', form='formatted', iostat=status)
      if (status /= 0) then
        call err%set(ERR_IO, "history file '"//self%path//"' exists but cannot be read")
        call stream_close(out, err)
        call remove_file(temporary, ignored)
        return
      end if
      first = .true.
      do
        read (in_unit, '(a)', iostat=status) line
        if (status /= 0) exit
        if (first) then
          first = .false.
          if (trim(line) /= history_header) then
            call err%set(ERR_IO, "history file '"//self%path//"' has other columns than this version "// &
                         "of ricochet writes; move it away to restart")
            close (in_unit)
            call stream_close(out, err)
            call remove_file(temporary, ignored)
            return
          end if
          cycle
        end if
        ! A row cut short by a crash has fewer columns, or no readable time: drop it.
        if (count_columns(line) /= n_columns) cycle
        read (line, *, iostat=status) row_time
        if (status /= 0) cycle
        if (row_time <= restart_time) call stream_write(out, trim(line), err, line=.true.)
        if (err%failed()) exit
      end do
      close (in_unit)
    end if
    call stream_close(out, err)
    if (err%failed()) then
      ! the old history.csv stays as it was
      call remove_file(temporary, ignored)
      return
    end if
    call rename_file(temporary, self%path, err)
    if (err%failed()) return
    call stream_open(self%path, 'a', self%stream, err)
    self%is_open = err%ok()
  end subroutine init_on_root

  !> Appends one row and flushes it (collective so that every rank sees an error).
  subroutine history_write(self, par, rec, err)
    class(history_writer_t), intent(inout) :: self
    type(parallel_t), intent(in) :: par
    type(history_record_t), intent(in) :: rec
    type(error_t), intent(inout) :: err
    character(len=line_length) :: row
    integer :: status
    if (par%is_root()) then
      if (.not. self%is_open) then
        call err%set(ERR_IO, 'history file written before it was opened')
      else
        write (row, row_format, iostat=status) rec%time, rec%dt, rec%steps, rec%kinetic_translational, &
          rec%kinetic_rotational, rec%potential, &
          rec%kinetic_translational + rec%kinetic_rotational + rec%potential, &
          rec%momentum, rec%angular_momentum, rec%wall_time, rec%events, rec%contacts, &
          rec%advancement_iterations, rec%min_separation, rec%asleep
        if (status /= 0) then
          call err%set(ERR_INTERNAL, "history file '"//self%path//"': a row does not fit its format")
        else
          ! A row cut short here (full disk) is dropped by a restart, as after a crash.
          call stream_write(self%stream, trim(row), err, line=.true.)
          if (err%failed()) call err%prefix('history: ')
        end if
      end if
    end if
    call agree(par, err, 'history file: failed on rank 0')
  end subroutine history_write

  subroutine history_free(self)
    class(history_writer_t), intent(inout) :: self
    type(error_t) :: ignored
    if (self%is_open) call stream_close(self%stream, ignored)
    self%is_open = .false.
    if (allocated(self%path)) deallocate (self%path)
  end subroutine history_free

  pure integer function count_columns(line)
    character(len=*), intent(in) :: line
    integer :: i
    count_columns = 1
    do i = 1, len_trim(line)
      if (line(i:i) == ',') count_columns = count_columns + 1
    end do
  end function count_columns

  !> Every rank learns that some rank failed; ranks without their own message get `message`.
  subroutine agree(par, err, message)
    type(parallel_t), intent(in) :: par
    type(error_t), intent(inout) :: err
    character(len=*), intent(in) :: message
    if (par%any(err%failed()) .and. err%ok()) call err%set(ERR_IO, message)
  end subroutine agree

end module history_writer
