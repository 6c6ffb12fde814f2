!> The &parallel group of a deck (docs/input.md): how a run on several ranks is cut into
!> bricks. Its variables, the namelist read with the defaults reset, its rules, and its text
!> in the effective deck. Whether the dims fit the ranks and the scene is known only at run
!> time (simulation: domain decomposition), which names this group then.
module parallel_group
  use error_status, only: error_t
  use kinds, only: dp
  use string_utils, only: str
  use input_config, only: parallel_config_t
  use namelist_source, only: DECK_AUTO, V_INTEGER, V_REAL, var_spec_t, source_t, group_t, group_input_t, open_group, &
                             prepare_group, translate_read_error, fail, put_integer, put_real, require_finite, &
                             real_text
  use deck_sink, only: deck_sink_t
  implicit none
  private
  public :: read_parallel_group, write_parallel_group

  type(var_spec_t), parameter :: parallel_vars(3) = [var_spec_t('dims', V_INTEGER, 3, 0), &
                                                      var_spec_t('skin', V_REAL, 1, 0), &
                                                      var_spec_t('window_events', V_REAL, 1, 0)]

contains

  subroutine read_parallel_group(src, group, config, err)
    type(source_t), intent(in) :: src
    type(group_t), intent(in) :: group
    type(parallel_config_t), intent(out) :: config
    type(error_t), intent(inout) :: err
    type(group_input_t) :: g
    integer :: dims(3), ios
    real(dp) :: skin, window_events
    character(len=512) :: msg
    namelist /parallel/ dims, skin, window_events

    call open_group(src, group, parallel_vars, '&parallel', g)
    call prepare_group(g, err)
    if (err%failed()) return
    ! Defaults reset before the read: config is intent(out), so it holds the type's defaults.
    dims = config%dims
    skin = config%skin
    window_events = config%window_events
    msg = ''
    read (g%text, nml=parallel, iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call translate_read_error(g, ios, msg, err)
      return
    end if
    config%dims = dims
    config%skin = skin
    config%window_events = window_events
    call require_finite(g, err, 'skin', [skin])
    if (err%failed()) return
    call require_finite(g, err, 'window_events', [window_events])
    if (err%failed()) return
    if (window_events /= DECK_AUTO .and. .not. window_events >= 1.0_dp) &
      call fail(g, err, 'window_events', 'window_events must be >= 1 event, or -1 for auto, got '// &
                real_text(window_events))
    if (err%failed()) return
    if (skin /= DECK_AUTO .and. skin < 0.0_dp) call fail(g, err, 'skin', 'skin must be >= 0 m, or -1 for auto, got '// &
                                                          real_text(skin))
    if (err%failed()) return
    if (any(dims < 0)) call fail(g, err, 'dims', 'dims must be >= 0 ranks along each of x, y, z (0: chosen), got '// &
                                 str(dims(1))//', '//str(dims(2))//', '//str(dims(3)))
  end subroutine read_parallel_group

  !> The group in the effective deck: every variable, defaults filled in.
  subroutine write_parallel_group(config, out)
    type(parallel_config_t), intent(in) :: config
    type(deck_sink_t), intent(inout) :: out
    character(len=:), allocatable :: note
    call out%put('&parallel')
    call put_integer(out, 'dims', config%dims, 'ranks along x, y, z; 0: chosen')
    note = '[m] how far a body may leave its brick before it migrates'
    if (config%skin == DECK_AUTO) note = '[m] -1: auto, one box of the collision grid'
    call put_real(out, 'skin', [config%skin], note)
    note = '[-] events per rank a cross-rank window aims at'
    if (config%window_events == DECK_AUTO) note = '[-] -1: auto, 150 events per rank a cross-rank window'
    call put_real(out, 'window_events', [config%window_events], note)
    call out%put('/')
  end subroutine write_parallel_group

end module parallel_group
