!> Refuses a deck whose minimum separation is finer than positions can be told apart where
!> the bodies are: gaps are differences of world coordinates, so near |x| = L they are
!> known only to about spacing(L) (the distance between neighbouring doubles, 2.2e-16 L).
!> A 1e-8 m grain on a 1e4 m planet (auto min_separation 2e-12 m, where the planet's
!> surface reaches |x| = 2e4 m, spacing 3.6e-12 m) was taken below min_separation/2 in
!> both event loops, and a 1e-9 m grain stalled or hung the run; rather than break the
!> no-interpenetration promise silently, the run does not start.
module resolution_check
  use kinds, only: dp
  use error_status, only: error_t, ERR_INPUT
  use string_utils, only: str
  use input_config, only: deck_t
  use shape, only: shape_library_t
  use body_state, only: bodies_t
  implicit none
  private
  public :: check_position_resolution, resolution_spacings

  !> min_separation must span this many spacings of the largest coordinate. The gap of a
  !> pair carries a few roundings of coordinates of that size (positions, their difference,
  !> the norm, the radii): measured on a 1e-8..1e-7 m grain on a 1e4 m sphere, the
  !> min_separation/2 floor broke at 0.55 spacings and held from 0.82 up (docs/input.md);
  !> 4 keeps a factor of 7 over the break and admits 1e-7 m on 1e4 m (5.5 spacings).
  real(dp), parameter :: resolution_spacings = 4.0_dp

contains

  !> bodies must hold every body of the run (all ranks check the same, so all agree).
  !> target: the run's minimum separation [m]; auto: whether it is the auto value.
  subroutine check_position_resolution(deck, shapes, bodies, target, auto, err)
    type(deck_t), intent(in) :: deck
    type(shape_library_t), intent(in) :: shapes
    type(bodies_t), intent(in) :: bodies
    real(dp), intent(in) :: target
    logical, intent(in) :: auto
    type(error_t), intent(inout) :: err
    real(dp) :: reach, far_reach, extent, smallest
    integer :: i, far, small
    character(len=:), allocatable :: why, ratio
    far = 0
    small = 0
    far_reach = 0.0_dp
    smallest = huge(1.0_dp)
    do i = 1, bodies%n_owned
      associate (radius => shapes%shapes(bodies%shape_id(i))%bounding_radius)
        ! the farthest any point of the body's surface is along an axis
        reach = maxval(abs(bodies%x(:, i))) + radius
        if (reach > far_reach) then
          far_reach = reach
          far = i
        end if
        if (.not. bodies%fixed(i) .and. 2.0_dp*radius < smallest) then
          smallest = 2.0_dp*radius
          small = i
        end if
      end associate
    end do
    if (far == 0) return
    if (target >= resolution_spacings*spacing(far_reach)) return
    if (auto) then
      why = ' (auto: 1e-4 of the smallest moving body, '//describe(deck, bodies, small)//', extent '// &
            str(smallest, '(es10.3)')//' m)'
    else
      why = ' (&contact min_separation)'
    end if
    extent = 2.0_dp*shapes%shapes(bodies%shape_id(far))%bounding_radius
    ratio = ''
    if (small > 0 .and. small /= far) ratio = '; size ratio '//str(extent/smallest, '(es8.1)')//' of '// &
                                              describe(deck, bodies, far)//' to '//describe(deck, bodies, small)
    call err%set(ERR_INPUT, deck%path//': &contact: min_separation = '//str(target, '(es10.3)')//' m'//why// &
                 ' is below what positions resolve: '//describe(deck, bodies, far)//' reaches |x| = '// &
                 str(far_reach, '(es10.3)')//' m, where doubles are '//str(spacing(far_reach), '(es10.3)')// &
                 ' m apart, and min_separation must be at least '// &
                 str(resolution_spacings*spacing(far_reach), '(es10.3)')//' m ('//str(nint(resolution_spacings))// &
                 ' spacings)'//ratio//': set a larger &contact min_separation, bring the bodies nearer the '// &
                 'origin, or narrow the range of sizes')
  end subroutine check_position_resolution

  function describe(deck, bodies, i) result(text)
    type(deck_t), intent(in) :: deck
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: i
    character(len=:), allocatable :: text
    text = '&body #'//str(bodies%group_id(i))//" '"//trim(deck%bodies(bodies%group_id(i))%name)//"' (body "// &
           str(bodies%gid(i))//')'
  end function describe

end module resolution_check
