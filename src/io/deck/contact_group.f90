!> The &contact group of a deck (docs/input.md): restitution, friction and how a pair
!> combines its bodies' values, minimum separation, resting and sleeping thresholds, the
!> contact pass's turning term. Its variables, the namelist read with the defaults
!> reset, its rules, and its text in the effective deck.
module contact_group
  use kinds, only: dp
  use error_status, only: error_t
  use string_utils, only: lower
  use input_config, only: contact_config_t, RULE_MIN, RULE_MAX, RULE_MEAN, RULE_GEOMETRIC
  use namelist_source, only: DECK_AUTO, V_REAL, V_LOGICAL, V_CHARACTER, var_spec_t, source_t, group_t, group_input_t, &
                             open_group, prepare_group, translate_read_error, require_finite, fail, real_text, &
                             put_real, put_logical, put_text
  use deck_sink, only: deck_sink_t
  implicit none
  private
  public :: read_contact_group, write_contact_group

  type(contact_config_t), parameter :: contact_default = contact_config_t()

  type(var_spec_t), parameter :: contact_vars(9) = [ &
    var_spec_t('restitution', V_REAL, 1, 0), var_spec_t('friction', V_REAL, 1, 0), &
    var_spec_t('min_separation', V_REAL, 1, 0), var_spec_t('rest_speed', V_REAL, 1, 0), &
    var_spec_t('sleep_speed', V_REAL, 1, 0), var_spec_t('sleep_time', V_REAL, 1, 0), &
    var_spec_t('restitution_rule', V_CHARACTER, 1, len(contact_default%restitution_rule)), &
    var_spec_t('friction_rule', V_CHARACTER, 1, len(contact_default%friction_rule)), &
    var_spec_t('turning_term', V_LOGICAL, 1, 0)]

contains

  subroutine read_contact_group(src, group, config, err)
    type(source_t), intent(in) :: src
    type(group_t), intent(in) :: group
    type(contact_config_t), intent(out) :: config
    type(error_t), intent(inout) :: err
    type(group_input_t) :: g
    real(dp) :: restitution, friction, min_separation, rest_speed, sleep_speed, sleep_time
    character(len=len(config%restitution_rule)) :: restitution_rule
    character(len=len(config%friction_rule)) :: friction_rule
    logical :: turning_term
    integer :: ios
    character(len=512) :: msg
    namelist /contact/ restitution, friction, min_separation, rest_speed, sleep_speed, sleep_time, &
      restitution_rule, friction_rule, turning_term

    call open_group(src, group, contact_vars, '&contact', g)
    call prepare_group(g, err)
    if (err%failed()) return
    restitution = config%restitution
    friction = config%friction
    min_separation = config%min_separation
    rest_speed = config%rest_speed
    sleep_speed = config%sleep_speed
    sleep_time = config%sleep_time
    restitution_rule = config%restitution_rule
    friction_rule = config%friction_rule
    turning_term = config%turning_term
    msg = ''
    read (g%text, nml=contact, iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call translate_read_error(g, ios, msg, err)
      return
    end if
    config%restitution = restitution
    config%friction = friction
    config%min_separation = min_separation
    config%rest_speed = rest_speed
    config%sleep_speed = sleep_speed
    config%sleep_time = sleep_time
    config%restitution_rule = lower(adjustl(restitution_rule))
    config%friction_rule = lower(adjustl(friction_rule))
    config%turning_term = turning_term

    call require_finite(g, err, 'restitution', [restitution])
    call require_finite(g, err, 'friction', [friction])
    call require_finite(g, err, 'min_separation', [min_separation])
    call require_finite(g, err, 'rest_speed', [rest_speed])
    call require_finite(g, err, 'sleep_speed', [sleep_speed])
    call require_finite(g, err, 'sleep_time', [sleep_time])
    if (err%failed()) return
    if (restitution < 0.0_dp .or. restitution > 1.0_dp) then
      call fail(g, err, 'restitution', 'restitution must be in [0, 1], got '//real_text(restitution))
    else if (friction < 0.0_dp) then
      call fail(g, err, 'friction', 'friction must be >= 0, got '//real_text(friction))
    else if (min_separation /= DECK_AUTO .and. min_separation <= 0.0_dp) then
      ! 0 would let the time of contact collapse to zero (DEVELOPERS.md, the method).
      call fail(g, err, 'min_separation', 'min_separation must be > 0 m, or -1 for auto, got '// &
                real_text(min_separation))
    else if (rest_speed /= DECK_AUTO .and. rest_speed < 0.0_dp) then
      call fail(g, err, 'rest_speed', 'rest_speed must be >= 0 m/s, or -1 for auto, got '//real_text(rest_speed))
    else if (sleep_speed /= DECK_AUTO .and. sleep_speed < 0.0_dp) then
      call fail(g, err, 'sleep_speed', 'sleep_speed must be >= 0 m/s (0: never sleep), or -1 for auto, got '// &
                real_text(sleep_speed))
    else if (sleep_time <= 0.0_dp) then
      call fail(g, err, 'sleep_time', 'sleep_time must be > 0 s, got '//real_text(sleep_time))
    else if (config%restitution_rule /= RULE_MIN .and. config%restitution_rule /= RULE_MAX .and. &
             config%restitution_rule /= RULE_MEAN) then
      ! (no geometric mean for e: it is the rule for friction, where a zero must win)
      call fail(g, err, 'restitution_rule', 'unknown restitution_rule '''//trim(restitution_rule)// &
                ''' (known: '''//RULE_MIN//''', '''//RULE_MAX//''', '''//RULE_MEAN//''')')
    else if (config%friction_rule /= RULE_GEOMETRIC .and. config%friction_rule /= RULE_MIN .and. &
             config%friction_rule /= RULE_MAX .and. config%friction_rule /= RULE_MEAN) then
      call fail(g, err, 'friction_rule', 'unknown friction_rule '''//trim(friction_rule)//''' (known: '''// &
                RULE_GEOMETRIC//''', '''//RULE_MIN//''', '''//RULE_MAX//''', '''//RULE_MEAN//''')')
    end if
  end subroutine read_contact_group

  !> The group in the effective deck: every variable, defaults filled in, auto values as -1.
  subroutine write_contact_group(config, out)
    type(contact_config_t), intent(in) :: config
    type(deck_sink_t), intent(inout) :: out
    character(len=:), allocatable :: note
    call out%put('&contact')
    call put_real(out, 'restitution', [config%restitution], '')
    call put_real(out, 'friction', [config%friction], '')
    note = '[m]'
    if (config%min_separation == DECK_AUTO) note = '[m] -1: auto, 1e-4 of the smallest body size'
    call put_real(out, 'min_separation', [config%min_separation], note)
    note = '[m/s] below it impacts are inelastic'
    if (config%rest_speed == DECK_AUTO) note = '[m/s] -1: auto, max(2 |g| dt_max, sqrt(2 |g| min_separation))'
    call put_real(out, 'rest_speed', [config%rest_speed], note)
    note = '[m/s] 0: never sleep'
    if (config%sleep_speed == DECK_AUTO) note = '[m/s] -1: auto, rest_speed/100'
    call put_real(out, 'sleep_speed', [config%sleep_speed], note)
    call put_real(out, 'sleep_time', [config%sleep_time], '[s]')
    call put_text(out, 'restitution_rule', config%restitution_rule)
    call put_text(out, 'friction_rule', config%friction_rule)
    call put_logical(out, 'turning_term', config%turning_term)
    call out%put('/')
  end subroutine write_contact_group

end module contact_group
