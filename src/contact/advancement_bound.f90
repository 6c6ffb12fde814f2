!> Conservative advancement: how far two bodies can close the gap between them over a time
!> t, and the earliest time at which that bound reaches a given gap.
!>
!> Motion of a free body between impulses: its centre of mass follows x0 + v t + a t^2/2
!> (a = gravity: exact), and it rotates without torque, so kinetic energy T_rot = w.Jw/2 is
!> conserved and |w(t)| <= sqrt(2 T_rot / I_min) for all t (since w.Jw >= I_min |w|^2).
!> A point at distance at most r from the centre of mass therefore moves, relative to the
!> centre, at most Omega r per unit time. So along a unit direction n the displacement of
!> any point of body A obeys
!>     n.(p(t) - p(0)) <= n.v_A t + n.a_A t^2/2 + Omega_A r_A t        (D_A)
!> and for body B the same with >= and -Omega_B r_B. The gap between A and B measured along
!> n (from A to B) can shrink by at most
!>     closing(t) = (n.(v_A - v_B) + Omega_A r_A + Omega_B r_B) t + n.(a_A - a_B) t^2/2.
!> For convex bodies n is the closest-point normal (it separates them). For bodies that are
!> not convex a single direction does not bound the distance, and the bound in every
!> direction is used instead: |v_A - v_B| t + |a_A - a_B| t^2/2 + (Omega_A r_A + Omega_B r_B) t
!> (the distance between two sets is 1-Lipschitz in each point's motion).
module advancement_bound
  use kinds, only: dp
  implicit none
  private
  public :: angular_speed_bound, closing_bound_along, closing_bound_any, time_to_close, closing_distance

  !> The closing bound as b t + a t^2/2 (b: rate [m/s], a: acceleration [m/s^2]).
  type, public :: closing_bound_t
    real(dp) :: rate = 0.0_dp
    real(dp) :: acceleration = 0.0_dp
  end type closing_bound_t

contains

  !> Bound on |w(t)| for all t of a torque-free body with principal moments `inertia` and
  !> body-frame angular velocity w_body: sqrt(2 T / I_min) = sqrt(w.Jw / I_min) >= |w|.
  pure real(dp) function angular_speed_bound(inertia, w_body)
    real(dp), intent(in) :: inertia(3), w_body(3)
    real(dp) :: i_min
    i_min = minval(inertia)
    if (i_min <= 0.0_dp) then
      angular_speed_bound = 0.0_dp
    else
      ! max with |w| guards the last bit of round-off (the two are equal for a sphere).
      angular_speed_bound = max(sqrt(sum(inertia*w_body*w_body)/i_min), norm2(w_body))
    end if
  end function angular_speed_bound

  !> Closing bound along the unit normal n from A to B (convex pairs).
  pure function closing_bound_along(n, v_a, a_a, omega_r_a, v_b, a_b, omega_r_b) result(bound)
    real(dp), intent(in) :: n(3), v_a(3), a_a(3), omega_r_a, v_b(3), a_b(3), omega_r_b
    type(closing_bound_t) :: bound
    bound%rate = dot_product(n, v_a - v_b) + omega_r_a + omega_r_b
    bound%acceleration = dot_product(n, a_a - a_b)
  end function closing_bound_along

  !> Closing bound in every direction (any pair, convex or not).
  pure function closing_bound_any(v_a, a_a, omega_r_a, v_b, a_b, omega_r_b) result(bound)
    real(dp), intent(in) :: v_a(3), a_a(3), omega_r_a, v_b(3), a_b(3), omega_r_b
    type(closing_bound_t) :: bound
    bound%rate = norm2(v_a - v_b) + omega_r_a + omega_r_b
    bound%acceleration = norm2(a_a - a_b)
  end function closing_bound_any

  !> The bound's value at time t [m].
  pure real(dp) function closing_distance(bound, t)
    type(closing_bound_t), intent(in) :: bound
    real(dp), intent(in) :: t
    closing_distance = bound%rate*t + 0.5_dp*bound%acceleration*t*t
  end function closing_distance

  !> Earliest t > 0 at which the bound can close a gap s > 0; huge() if it never can.
  !> Solves b t + a t^2/2 = s in the form t = 2 s / (b + sqrt(b^2 + 2 a s)), which has no
  !> cancellation when b > 0 (the usual case) and is exact for a = 0.
  !> For s = 0 it is the time until the bound may turn positive: 0 if the pair may be
  !> closing now, -2b/a if it separates and then returns, huge() if it never closes.
  pure real(dp) function time_to_close(bound, gap)
    type(closing_bound_t), intent(in) :: bound
    real(dp), intent(in) :: gap
    real(dp) :: b, a, disc, denominator
    b = bound%rate
    a = bound%acceleration
    if (gap <= 0.0_dp) then
      if (b > 0.0_dp .or. (b == 0.0_dp .and. a > 0.0_dp)) then
        time_to_close = 0.0_dp
      else if (a > 0.0_dp) then
        time_to_close = -2.0_dp*b/a
      else
        time_to_close = huge(1.0_dp)
      end if
      return
    end if
    disc = b*b + 2.0_dp*a*gap
    if (disc < 0.0_dp) then
      time_to_close = huge(1.0_dp)        ! decelerating: turns back before closing the gap
      return
    end if
    denominator = b + sqrt(disc)
    if (denominator <= 0.0_dp) then
      time_to_close = huge(1.0_dp)        ! receding and not accelerating towards
    else
      time_to_close = 2.0_dp*gap/denominator
    end if
  end function time_to_close

end module advancement_bound
