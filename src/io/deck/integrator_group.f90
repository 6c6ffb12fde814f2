!> The &integrator group of a deck (docs/input.md): Newmark parameters, the rotation update
!> and its iteration, the event loop. Its variables, the namelist read with the defaults reset, its rules,
!> and its text in the effective deck.
module integrator_group
  use kinds, only: dp
  use error_status, only: error_t
  use string_utils, only: str, lower
  use input_config, only: integrator_config_t, ROTATION_NEWMARK, ROTATION_EXACT, EVENTS_AUTO, EVENTS_LOCAL, &
                          EVENTS_GLOBAL
  use namelist_source, only: V_REAL, V_INTEGER, V_LOGICAL, V_CHARACTER, var_spec_t, source_t, group_t, group_input_t, &
                             open_group, prepare_group, translate_read_error, require_finite, fail, real_text, &
                             put_real, put_integer, put_text, put_logical
  use deck_sink, only: deck_sink_t
  implicit none
  private
  public :: read_integrator_group, write_integrator_group

  type(integrator_config_t), parameter :: integrator_default = integrator_config_t()

  type(var_spec_t), parameter :: integrator_vars(7) = [ &
    var_spec_t('newmark_beta', V_REAL, 1, 0), var_spec_t('newmark_gamma', V_REAL, 1, 0), &
    var_spec_t('rotation_tolerance', V_REAL, 1, 0), var_spec_t('rotation_max_iterations', V_INTEGER, 1, 0), &
    var_spec_t('rotation', V_CHARACTER, 1, len(integrator_default%rotation)), &
    var_spec_t('events', V_CHARACTER, 1, len(integrator_default%events)), &
    var_spec_t('audit_certificates', V_LOGICAL, 1, 0)]

contains

  subroutine read_integrator_group(src, group, config, err)
    type(source_t), intent(in) :: src
    type(group_t), intent(in) :: group
    type(integrator_config_t), intent(out) :: config
    type(error_t), intent(inout) :: err
    type(group_input_t) :: g
    real(dp) :: newmark_beta, newmark_gamma, rotation_tolerance
    integer :: rotation_max_iterations
    character(len=len(config%rotation)) :: rotation
    character(len=len(config%events)) :: events
    logical :: audit_certificates
    integer :: ios
    character(len=512) :: msg
    namelist /integrator/ newmark_beta, newmark_gamma, rotation_tolerance, rotation_max_iterations, rotation, events, &
                          audit_certificates

    call open_group(src, group, integrator_vars, '&integrator', g)
    call prepare_group(g, err)
    if (err%failed()) return
    newmark_beta = config%newmark_beta
    newmark_gamma = config%newmark_gamma
    rotation_tolerance = config%rotation_tolerance
    rotation_max_iterations = config%rotation_max_iterations
    rotation = config%rotation
    events = config%events
    audit_certificates = config%audit_certificates
    msg = ''
    read (g%text, nml=integrator, iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call translate_read_error(g, ios, msg, err)
      return
    end if
    config%newmark_beta = newmark_beta
    config%newmark_gamma = newmark_gamma
    config%rotation_tolerance = rotation_tolerance
    config%rotation_max_iterations = rotation_max_iterations
    config%rotation = lower(adjustl(rotation))
    config%events = lower(adjustl(events))
    config%audit_certificates = audit_certificates

    call require_finite(g, err, 'newmark_beta', [newmark_beta])
    call require_finite(g, err, 'newmark_gamma', [newmark_gamma])
    call require_finite(g, err, 'rotation_tolerance', [rotation_tolerance])
    if (err%failed()) return
    ! Newmark is unconditionally stable for 2 beta >= gamma >= 1/2; gamma < 1/2 amplifies
    ! errors (unstable), gamma > 1/2 adds numerical damping (first order), beta > 1/2 is
    ! outside the family's useful range. beta < gamma/2 (e.g. beta = 0, explicit) is allowed:
    ! it is only conditionally stable, which free flight between contacts does not stress.
    if (newmark_beta < 0.0_dp .or. newmark_beta > 0.5_dp) then
      call fail(g, err, 'newmark_beta', 'newmark_beta must be in [0, 0.5], got '//real_text(newmark_beta)// &
                ' (unconditional stability needs 2 beta >= gamma >= 1/2)')
    else if (newmark_gamma < 0.5_dp .or. newmark_gamma > 1.0_dp) then
      call fail(g, err, 'newmark_gamma', 'newmark_gamma must be in [0.5, 1], got '//real_text(newmark_gamma)// &
                ' (gamma < 1/2 is unstable; gamma > 1/2 damps, 2 beta >= gamma >= 1/2 is unconditionally stable)')
    else if (rotation_tolerance <= 0.0_dp .or. rotation_tolerance >= 1.0_dp) then
      call fail(g, err, 'rotation_tolerance', 'rotation_tolerance must be in (0, 1) (a relative change), got '// &
                real_text(rotation_tolerance))
    else if (rotation_max_iterations < 1) then
      call fail(g, err, 'rotation_max_iterations', 'rotation_max_iterations must be >= 1, got '// &
                str(rotation_max_iterations))
    else if (config%rotation /= ROTATION_NEWMARK .and. config%rotation /= ROTATION_EXACT) then
      call fail(g, err, 'rotation', 'unknown rotation '''//trim(rotation)//''' (known: '''//ROTATION_NEWMARK// &
                ''', '''//ROTATION_EXACT//''')')
    else if (config%events /= EVENTS_AUTO .and. config%events /= EVENTS_LOCAL .and. &
             config%events /= EVENTS_GLOBAL) then
      call fail(g, err, 'events', 'unknown events '''//trim(events)//''' (known: '''//EVENTS_AUTO// &
                ''', '''//EVENTS_LOCAL//''', '''//EVENTS_GLOBAL//''')')
    end if
  end subroutine read_integrator_group

  !> The group in the effective deck: every variable, defaults filled in.
  subroutine write_integrator_group(config, out)
    type(integrator_config_t), intent(in) :: config
    type(deck_sink_t), intent(inout) :: out
    call out%put('&integrator')
    call put_real(out, 'newmark_beta', [config%newmark_beta], '')
    call put_real(out, 'newmark_gamma', [config%newmark_gamma], '')
    call put_real(out, 'rotation_tolerance', [config%rotation_tolerance], '[-] relative')
    call put_integer(out, 'rotation_max_iterations', [config%rotation_max_iterations], '')
    call put_text(out, 'rotation', config%rotation)
    call put_text(out, 'events', config%events)
    call put_logical(out, 'audit_certificates', config%audit_certificates)
    call out%put('/')
  end subroutine write_integrator_group

end module integrator_group
