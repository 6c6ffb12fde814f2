!> The &output group of a deck (docs/input.md): the output folder, frame, checkpoint,
!> progress and history intervals, what is written. Its variables, the namelist read with
!> the defaults reset, its rules, and its text in the effective deck.
module output_group
  use kinds, only: dp
  use error_status, only: error_t
  use string_utils, only: str
  use input_config, only: output_config_t
  use namelist_source, only: DECK_AUTO, V_REAL, V_LOGICAL, V_CHARACTER, var_spec_t, source_t, group_t, &
                             group_input_t, open_group, prepare_group, translate_read_error, require_finite, fail, &
                             real_text, put_real, put_logical, put_text
  use deck_paths, only: resolve_path
  use deck_sink, only: deck_sink_t
  implicit none
  private
  public :: read_output_group, write_output_group

  type(output_config_t), parameter :: output_default = output_config_t()

  type(var_spec_t), parameter :: output_vars(8) = [ &
    var_spec_t('dir', V_CHARACTER, 1, len(output_default%dir)), var_spec_t('interval', V_REAL, 1, 0), &
    var_spec_t('checkpoint_interval', V_REAL, 1, 0), var_spec_t('progress_interval', V_REAL, 1, 0), &
    var_spec_t('history_interval', V_REAL, 1, 0), var_spec_t('write_frames', V_LOGICAL, 1, 0), &
    var_spec_t('check_overlaps', V_LOGICAL, 1, 0), var_spec_t('event_log', V_LOGICAL, 1, 0)]

contains

  subroutine read_output_group(src, group, folder, config, err)
    type(source_t), intent(in) :: src
    type(group_t), intent(in) :: group
    character(len=*), intent(in) :: folder
    type(output_config_t), intent(out) :: config
    type(error_t), intent(inout) :: err
    type(group_input_t) :: g
    character(len=len(config%dir)) :: dir
    real(dp) :: interval, checkpoint_interval, progress_interval, history_interval
    logical :: write_frames, check_overlaps, event_log
    character(len=:), allocatable :: resolved
    integer :: ios
    character(len=512) :: msg
    namelist /output/ dir, interval, checkpoint_interval, progress_interval, history_interval, write_frames, &
      check_overlaps, event_log

    call open_group(src, group, output_vars, '&output', g)
    call prepare_group(g, err)
    if (err%failed()) return
    dir = config%dir
    interval = config%interval
    checkpoint_interval = config%checkpoint_interval
    progress_interval = config%progress_interval
    history_interval = config%history_interval
    write_frames = config%write_frames
    check_overlaps = config%check_overlaps
    event_log = config%event_log
    msg = ''
    read (g%text, nml=output, iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call translate_read_error(g, ios, msg, err)
      return
    end if
    config%interval = interval
    config%checkpoint_interval = checkpoint_interval
    config%progress_interval = progress_interval
    config%history_interval = history_interval
    config%write_frames = write_frames
    config%check_overlaps = check_overlaps
    config%event_log = event_log

    call require_finite(g, err, 'interval', [interval])
    call require_finite(g, err, 'history_interval', [history_interval])
    call require_finite(g, err, 'checkpoint_interval', [checkpoint_interval])
    call require_finite(g, err, 'progress_interval', [progress_interval])
    if (err%failed()) return
    if (len_trim(dir) == 0) then
      call fail(g, err, 'dir', 'dir must not be blank')
      return
    end if
    resolved = resolve_path(folder, dir)
    if (len(resolved) > len(config%dir)) then
      call fail(g, err, 'dir', 'dir resolved against the deck''s folder is longer than '// &
                str(len(config%dir))//' characters')
      return
    end if
    config%dir = resolved
    if (interval /= DECK_AUTO .and. interval <= 0.0_dp) then
      call fail(g, err, 'interval', 'interval must be > 0 s, or -1 for auto (t_end/100), got '// &
                real_text(interval))
    else if (checkpoint_interval < 0.0_dp) then
      call fail(g, err, 'checkpoint_interval', 'checkpoint_interval must be >= 0 s (0: only at the end), got '// &
                real_text(checkpoint_interval))
    else if (progress_interval <= 0.0_dp) then
      call fail(g, err, 'progress_interval', 'progress_interval must be > 0 s, got '//real_text(progress_interval))
    else if (history_interval /= DECK_AUTO .and. history_interval <= 0.0_dp) then
      call fail(g, err, 'history_interval', 'history_interval must be > 0 s, or -1 for auto (interval/10), got '// &
                real_text(history_interval))
    end if
  end subroutine read_output_group

  !> The group in the effective deck: every variable, defaults filled in, auto values as -1.
  subroutine write_output_group(config, out)
    type(output_config_t), intent(in) :: config
    type(deck_sink_t), intent(inout) :: out
    character(len=:), allocatable :: note
    call out%put('&output')
    call put_text(out, 'dir', config%dir)
    note = '[s]'
    if (config%interval == DECK_AUTO) note = '[s] -1: auto, t_end/100'
    call put_real(out, 'interval', [config%interval], note)
    call put_real(out, 'checkpoint_interval', [config%checkpoint_interval], '[s] 0: only at the end')
    call put_real(out, 'progress_interval', [config%progress_interval], '[s of wall time]')
    note = '[s]'
    if (config%history_interval == DECK_AUTO) note = '[s] -1: auto, interval/10'
    call put_real(out, 'history_interval', [config%history_interval], note)
    call put_logical(out, 'write_frames', config%write_frames)
    call put_logical(out, 'check_overlaps', config%check_overlaps)
    call put_logical(out, 'event_log', config%event_log)
    call out%put('/')
  end subroutine write_output_group

end module output_group
