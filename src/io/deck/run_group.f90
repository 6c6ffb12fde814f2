!> The &run group of a deck (docs/input.md): title, end time, largest step, gravity, wall
!> limit. Its variables, the namelist read with the defaults reset, its rules, and its text
!> in the effective deck.
module run_group
  use kinds, only: dp
  use error_status, only: error_t
  use input_config, only: run_config_t
  use namelist_source, only: V_REAL, V_CHARACTER, var_spec_t, source_t, group_t, group_input_t, open_group, &
                             prepare_group, translate_read_error, require_finite, given, fail, real_text, &
                             put_real, put_text
  use deck_sink, only: deck_sink_t
  implicit none
  private
  public :: read_run_group, write_run_group

  type(run_config_t), parameter :: run_default = run_config_t()

  type(var_spec_t), parameter :: run_vars(5) = [ &
    var_spec_t('title', V_CHARACTER, 1, len(run_default%title)), var_spec_t('t_end', V_REAL, 1, 0), &
    var_spec_t('dt_max', V_REAL, 1, 0), var_spec_t('gravity', V_REAL, 3, 0), &
    var_spec_t('wall_limit', V_REAL, 1, 0)]

contains

  subroutine read_run_group(src, group, config, err)
    type(source_t), intent(in) :: src
    type(group_t), intent(in) :: group
    type(run_config_t), intent(out) :: config
    type(error_t), intent(inout) :: err
    type(group_input_t) :: g
    character(len=len(config%title)) :: title
    real(dp) :: t_end, dt_max, gravity(3), wall_limit
    integer :: ios
    character(len=512) :: msg
    namelist /run/ title, t_end, dt_max, gravity, wall_limit

    call open_group(src, group, run_vars, '&run', g)
    call prepare_group(g, err)
    if (err%failed()) return
    ! Defaults reset before the read: config is intent(out), so it holds the type's defaults.
    title = config%title
    t_end = config%t_end
    dt_max = config%dt_max
    gravity = config%gravity
    wall_limit = config%wall_limit
    msg = ''
    read (g%text, nml=run, iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call translate_read_error(g, ios, msg, err)
      return
    end if
    config%title = title
    config%t_end = t_end
    config%dt_max = dt_max
    config%gravity = gravity
    config%wall_limit = wall_limit

    call require_finite(g, err, 't_end', [t_end])
    call require_finite(g, err, 'dt_max', [dt_max])
    call require_finite(g, err, 'gravity', gravity)
    call require_finite(g, err, 'wall_limit', [wall_limit])
    if (err%failed()) return
    if (.not. given(g, 't_end')) then
      call fail(g, err, '', 't_end is required (end time of the run [s])')
    else if (t_end <= 0.0_dp) then
      call fail(g, err, 't_end', 't_end must be > 0 s, got '//real_text(t_end))
    else if (.not. given(g, 'dt_max')) then
      call fail(g, err, '', 'dt_max is required (largest time step [s])')
    else if (dt_max <= 0.0_dp) then
      call fail(g, err, 'dt_max', 'dt_max must be > 0 s, got '//real_text(dt_max))
    else if (dt_max > t_end) then
      call fail(g, err, 'dt_max', 'dt_max = '//real_text(dt_max)//' s must not exceed t_end = '// &
                real_text(t_end)//' s')
    else if (wall_limit < 0.0_dp) then
      call fail(g, err, 'wall_limit', 'wall_limit must be >= 0 s (0: no limit), got '//real_text(wall_limit))
    end if
  end subroutine read_run_group

  !> The group in the effective deck: every variable, defaults filled in.
  subroutine write_run_group(config, out)
    type(run_config_t), intent(in) :: config
    type(deck_sink_t), intent(inout) :: out
    call out%put('&run')
    call put_text(out, 'title', config%title)
    call put_real(out, 't_end', [config%t_end], '[s]')
    call put_real(out, 'dt_max', [config%dt_max], '[s]')
    call put_real(out, 'gravity', config%gravity, '[m/s^2]')
    call put_real(out, 'wall_limit', [config%wall_limit], '[s] 0: no limit')
    call out%put('/')
  end subroutine write_run_group

end module run_group
