!> History CSV: header, rows that read back exactly, restart trimming (rows after the
!> restart time and a row cut short by a crash are dropped), a foreign header refused.
program test_history_writer
  use kinds, only: dp, i8
  use error_status, only: error_t
  use parallel_env, only: parallel_t
  use history_writer, only: history_writer_t, history_record_t, history_fresh_start, history_header
  use assertions
  implicit none
  type(parallel_t) :: par
  type(error_t) :: err
  type(history_writer_t) :: history
  type(history_record_t) :: rec
  real(dp), allocatable :: table(:, :)
  integer :: i, unit

  call par%init()
  call history%init(par, 'out/history.csv', history_fresh_start, err)
  call check(err%ok(), 'init creates the folder and the file: '//text(err))
  do i = 0, 4
    call history%write(par, record(i), err)
  end do
  call check(err%ok(), 'five rows written: '//text(err))
  ! Read while still open: every row is flushed as written.
  call read_table('out/history.csv', table)
  call check(size(table, 2) == 5, 'five rows readable while the run goes on')
  call check(size(table, 1) == 14, 'fourteen columns')
  rec = record(3)
  ! Exact: es24.16 prints 17 significant digits, enough to round-trip any double.
  call check(table(1, 4) == rec%time .and. table(2, 4) == rec%dt, 'time and dt read back exactly')
  call check(nint(table(3, 4), i8) == rec%steps, 'steps')
  call check(all(table(4:7, 4) == [rec%kinetic_translational, rec%kinetic_rotational, rec%potential, &
                                   rec%kinetic_translational + rec%kinetic_rotational + rec%potential]), &
             'energies and their total')
  call check(all(table(8:10, 4) == rec%momentum) .and. all(table(11:13, 4) == rec%angular_momentum), &
             'momenta read back exactly')
  call check(table(14, 4) == rec%wall_time, 'wall time')
  call history%free()

  ! A crash in the middle of a row leaves part of it; a restart later than every row keeps
  ! the complete rows only.
  open (newunit=unit, file='out/history.csv', position='append', action='write')
  write (unit, '(a)') ' 4.5000000000000000E-001, 1.0000'
  close (unit)
  call history%init(par, 'out/history.csv', 1.0_dp, err)
  call check(err%ok(), 'restart init after a crash: '//text(err))
  call history%free()
  call read_table('out/history.csv', table)
  call check(size(table, 2) == 5, 'the row cut short is dropped, the five complete rows kept')
  ! Restart at t = 0.2: rows at 0, 0.1, 0.2 stay, 0.3 and 0.4 go.
  call history%init(par, 'out/history.csv', record_time(2), err)
  call check(err%ok(), 'restart init: '//text(err))
  call read_table('out/history.csv', table)
  call check(size(table, 2) == 3, 'three rows kept at restart')
  call history%write(par, record(3), err)
  call history%free()
  call read_table('out/history.csv', table)
  call check(size(table, 2) == 4 .and. table(1, 4) == record_time(3), 'the run continues after the kept rows')
  call check(first_line('out/history.csv') == history_header, 'one header line')

  ! A fresh start replaces an old history.
  call history%init(par, 'out/history.csv', history_fresh_start, err)
  call history%free()
  call read_table('out/history.csv', table)
  call check(size(table, 2) == 0, 'a fresh run starts an empty table')

  ! Restarting onto a file from something else is refused, and the file is kept.
  open (newunit=unit, file='other.csv', status='replace', action='write')
  write (unit, '(a)') 'time,energy'
  write (unit, '(a)') '0.0,1.0'
  close (unit)
  call history%init(par, 'other.csv', 1.0_dp, err)
  call check_error(err%code, text(err), [character(len=40) :: "'other.csv'", 'other columns'], 'foreign header')
  call check(first_line('other.csv') == 'time,energy', 'the foreign file is left alone')
  call err%clear()
  call history%free()

  call par%free()
  call test_finish()

contains

  pure real(dp) function record_time(i)
    integer, intent(in) :: i
    record_time = 0.1_dp*i
  end function record_time

  !> Values with full mantissas and of very different sizes.
  function record(i) result(r)
    integer, intent(in) :: i
    type(history_record_t) :: r
    r%time = record_time(i)
    r%dt = 1.0e-3_dp/3.0_dp
    r%steps = 3000000000_i8 + i
    r%kinetic_translational = 1.0_dp/(i + 3)
    r%kinetic_rotational = sqrt(2.0_dp)*1.0e-20_dp
    r%potential = -9.81_dp*i/7.0_dp
    r%momentum = [1.0_dp/3.0_dp, -2.0e10_dp/7.0_dp, 0.0_dp]
    r%angular_momentum = [-1.0e-300_dp, 1.0e300_dp, real(i, dp)]
    r%wall_time = 0.5_dp*i
  end function record

  subroutine read_table(path, values)
    character(len=*), intent(in) :: path
    real(dp), allocatable, intent(out) :: values(:, :)
    real(dp) :: row(14)
    character(len=2048) :: line
    integer :: unit, status, n
    allocate (values(14, 0))
    open (newunit=unit, file=path, status='old', action='read')
    read (unit, '(a)') line   ! header
    n = 0
    do
      read (unit, '(a)', iostat=status) line
      if (status /= 0) exit
      read (line, *) row
      values = reshape([values, row], [14, n + 1])
      n = n + 1
    end do
    close (unit)
  end subroutine read_table

  function first_line(path) result(line)
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: line
    character(len=2048) :: buffer
    integer :: unit
    open (newunit=unit, file=path, status='old', action='read')
    read (unit, '(a)') buffer
    close (unit)
    line = trim(buffer)
  end function first_line

  function text(e) result(message)
    type(error_t), intent(in) :: e
    character(len=:), allocatable :: message
    message = ''
    if (allocated(e%message)) message = e%message
  end function text

end program test_history_writer
