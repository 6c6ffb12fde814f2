!> The ricochet program: parse the command line, read the deck, run, report, exit with a
!> status. Everything else is in the library; errors come back here as one error_t and
!> leave as one line on stderr and a non-zero exit code.
program ricochet
  use, intrinsic :: iso_fortran_env, only: error_unit, output_unit
  use kinds, only: dp
  use error_status, only: error_t, ERR_INPUT, ERR_MESH, ERR_CHECKPOINT, ERR_IO
  use parallel_env, only: parallel_t
  use string_utils, only: join_path, str
  use input_config, only: deck_t
  use deck_reader, only: read_deck, write_effective_deck
  use shared_deck, only: read_deck_shared
  use simulation, only: simulation_t
  use startup_report, only: check_deck
  use stop_request, only: install_stop_handlers, exit_now
  use memory_policy, only: keep_freed_memory
  implicit none

  type(parallel_t) :: par
  type(error_t) :: err
  type(deck_t) :: deck
  type(simulation_t) :: sim
  character(len=:), allocatable :: deck_path, restart_path, mode, output_override
  character(len=4096) :: line
  integer :: report, status
  logical :: memory_kept
  real(dp) :: started_at   ! (a run's wall time counts from here: reading its deck included)

  call par%init()
  started_at = par%wtime()
  ! (large arrays rebuilt at every window then cost no page faults: memory_policy)
  memory_kept = keep_freed_memory()
  call parse_command_line(mode, deck_path, restart_path, output_override, err)
  if (err%failed()) call fail(par, err)

  select case (mode)
  case ('help')
    if (par%is_root()) call print_usage(output_unit)
  case ('version')
    if (par%is_root()) write (output_unit, '(a)') 'ricochet '//RICOCHET_VERSION
  case ('check')
    call read_deck(deck_path, deck, err)
    if (err%failed()) call fail(par, err)
    if (par%is_root()) then
      ! Every start-up check of a run first; "valid" only once they all passed.
      open (newunit=report, status='scratch', action='readwrite', form='formatted')
      call check_deck(deck, report, err)
      if (err%failed()) call fail(par, err)
      write (output_unit, '(a)') '! '//deck_path//': valid. Effective input, every default filled in:'
      call write_effective_deck(deck, output_unit)
      rewind (report)
      do
        read (report, '(a)', iostat=status) line
        if (status /= 0) exit
        write (output_unit, '(a)') trim(line)
      end do
      close (report)
    end if
  case ('output-dir')
    call read_deck(deck_path, deck, err)
    if (err%failed()) call fail(par, err)
    if (par%is_root()) write (output_unit, '(a)') output_dir_of(deck, output_override)
  case ('run')
    ! SIGTERM/SIGINT from here on stop the run cleanly with a checkpoint (docs/output.md).
    call install_stop_handlers(err)
    if (err%failed()) call fail(par, err)
    ! (every rank parses a share of the &body groups: shared_deck)
    call read_deck_shared(par, deck_path, deck, err)
    if (err%failed()) call fail(par, err)
    if (par%is_root()) then
      write (output_unit, '(a)') 'ricochet '//RICOCHET_VERSION//': '//trim(deck%run%title)//' ('//deck_path//')'
      if (len(restart_path) > 0) write (output_unit, '(a)') '  restarting from '//restart_path
      flush (output_unit)   ! stdout is block-buffered when redirected: keep the log whole
    end if
    call sim%init(par, deck, output_dir_of(deck, output_override), restart_path, err, started_at)
    if (err%failed()) call fail(par, err)
    call sim%run(par, err)
    if (err%failed()) call fail(par, err)
    if (sim%stop_code /= 0) call stop_early(par, sim, deck_path, output_override)
    call sim%summary(par)
    call sim%free()
  end select
  call par%free()

contains

  !> The deck's output folder (relative to the deck's folder), unless the command line
  !> overrides it (then relative to the working directory).
  function output_dir_of(deck, override) result(dir)
    type(deck_t), intent(in) :: deck
    character(len=*), intent(in) :: override
    character(len=:), allocatable :: dir
    if (len(override) > 0) then
      dir = override
    else
      dir = join_path(deck%folder, trim(deck%output%dir))
    end if
  end function output_dir_of

  subroutine parse_command_line(mode, deck_path, restart_path, output_override, err)
    character(len=:), allocatable, intent(out) :: mode, deck_path, restart_path, output_override
    type(error_t), intent(inout) :: err
    character(len=4096) :: arg
    integer :: i, n
    mode = 'run'
    deck_path = ''
    restart_path = ''
    output_override = ''
    n = command_argument_count()
    i = 0
    do while (i < n)
      i = i + 1
      call get_command_argument(i, arg)
      select case (trim(arg))
      case ('-h', '--help')
        mode = 'help'
        return
      case ('--version')
        mode = 'version'
        return
      case ('--check')
        mode = 'check'
      case ('--print-output-dir')
        mode = 'output-dir'
      case ('--restart')
        if (i == n) then
          call err%set(ERR_INPUT, '--restart needs a checkpoint file (ricochet DECK --restart FILE)')
          return
        end if
        i = i + 1
        call get_command_argument(i, arg)
        restart_path = trim(arg)
      case ('--output-dir')
        if (i == n) then
          call err%set(ERR_INPUT, '--output-dir needs a folder')
          return
        end if
        i = i + 1
        call get_command_argument(i, arg)
        output_override = trim(arg)
      case default
        if (arg(1:1) == '-') then
          call err%set(ERR_INPUT, "unknown option '"//trim(arg)//"' (ricochet --help lists the options)")
          return
        end if
        if (len(deck_path) > 0) then
          call err%set(ERR_INPUT, "one deck per run: got '"//deck_path//"' and '"//trim(arg)//"'")
          return
        end if
        deck_path = trim(arg)
      end select
    end do
    if (len(deck_path) == 0) call err%set(ERR_INPUT, 'no deck given (usage: ricochet [--check] DECK [--restart FILE])')
  end subroutine parse_command_line

  subroutine print_usage(unit)
    integer, intent(in) :: unit
    write (unit, '(a)') 'usage: ricochet DECK                  run the deck', &
      '       ricochet DECK --restart FILE    continue from a checkpoint of the same deck', &
      '       ricochet --check DECK          every start-up check without running: the effective input, '// &
      'the bodies (volume, mass, moments, axes), the smallest initial gap', &
      '       ricochet DECK --output-dir DIR  write output to DIR instead of the deck''s &output dir', &
      '       ricochet --print-output-dir DECK', &
      '       mpiexec -n N ricochet DECK     the same on N ranks', &
      'Decks are Fortran namelist files: see docs/input.md.'
  end subroutine print_usage

  !> The way out of a run stopped before t_end (signal or &run wall_limit), checkpoint
  !> written: one line saying why, when, where the checkpoint is and how to go on, then
  !> exit status 128 + signal (143 SIGTERM, 130 SIGINT) or 75 (wall_limit) on every rank.
  subroutine stop_early(par, sim, deck_path, output_override)
    type(parallel_t), intent(inout) :: par
    type(simulation_t), intent(in) :: sim
    character(len=*), intent(in) :: deck_path, output_override
    character(len=:), allocatable :: again
    integer :: code
    if (par%is_root()) then
      again = 'ricochet '//deck_path//' --restart '//sim%stop_checkpoint
      if (len(output_override) > 0) again = again//' --output-dir '//output_override
      write (output_unit, '(a)') 'ricochet: '//sim%stop_reason//' at t = '//str(sim%time, '(g0.10)')// &
        ' s (step '//str(sim%step)//'): checkpoint written to '//sim%stop_checkpoint//'; continue with: '//again
      flush (output_unit)
    end if
    code = sim%stop_code
    call par%free()
    stop code, quiet = .true.
  end subroutine stop_early

  !> The one way out on error: one line on stderr (from rank 0), then a non-zero exit on
  !> every rank (collective abort when there are several).
  subroutine fail(par, err)
    type(parallel_t), intent(inout) :: par
    type(error_t), intent(in) :: err
    ! Deck, mesh and checkpoint errors are seen alike by every rank: rank 0 speaks for all.
    ! Anything else may be one rank's alone, so that rank says it, naming itself.
    if (par%is_root()) then
      write (error_unit, '(a)') 'ricochet: error: '//err%message
    else if (all(err%code /= [ERR_INPUT, ERR_MESH, ERR_CHECKPOINT])) then
      write (error_unit, '(a,i0,a)') 'ricochet: error on rank ', par%rank, ': '//err%message
    end if
    flush (error_unit)
    if (par%n_ranks > 1) call par%abort(err%code)
    ! After a failed write HDF5 1.10 crashes in its shutdown (run by MPI_Finalize) on the
    ! file it could not close: leave without it, the error is said and stdout flushed.
    flush (output_unit)
    if (err%code == ERR_IO) call exit_now(err%code)
    call par%free()
    stop err%code, quiet = .true.
  end subroutine fail

end program ricochet
