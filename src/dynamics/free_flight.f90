!> Free flight of every owned body over one step, with the rotation method the deck chose:
!> 'newmark' (Newmark with the iterative implicit correction, newmark_integrator) or
!> 'exact' (the closed-form torque-free motion, free_rotation_exact). The centre of mass
!> always follows Newmark, which is the exact parabola under constant gravity.
module free_flight
  use kinds, only: dp
  use input_config, only: integrator_config_t, ROTATION_EXACT
  use body_state, only: bodies_t
  use newmark_integrator, only: advance_free_flight, newmark_translate, free_flight_stats_t
  use free_rotation_exact, only: exact_rotate
  implicit none
  private
  public :: advance_bodies

contains

  subroutine advance_bodies(bodies, h, gravity, config, stats)
    type(bodies_t), intent(inout) :: bodies
    real(dp), intent(in) :: h             !< step [s]
    real(dp), intent(in) :: gravity(3)    !< [m/s^2]
    type(integrator_config_t), intent(in) :: config
    type(free_flight_stats_t), intent(inout) :: stats
    integer :: i
    if (config%rotation /= ROTATION_EXACT) then
      call advance_free_flight(bodies, h, gravity, config, stats)
      return
    end if
    ! Exact rotation: no torque acts between contacts (gravity acts at the centre of mass),
    ! so the rotation is the free rigid body's, evaluated in closed form at any h.
    do i = 1, bodies%n_owned
      if (bodies%fixed(i)) cycle
      call newmark_translate(bodies%x(:, i), bodies%v(:, i), bodies%a(:, i), gravity, h, &
                             config%newmark_beta, config%newmark_gamma)
      call exact_rotate(bodies%q(:, i), bodies%w(:, i), bodies%inertia(:, i), h)
      stats%rotation_updates = stats%rotation_updates + 1
    end do
  end subroutine advance_bodies

end module free_flight
