!> Unit quaternions q = (w, x, y, z) for orientations. Convention used across ricochet:
!> q rotates body-frame vectors into the world frame, v_world = R(q) v_body, and
!> dq/dt = 1/2 q (x) (0, omega_body) = 1/2 (0, omega_world) (x) q.
module quaternion
  use kinds, only: dp
  use vector_ops, only: cross
  implicit none
  private
  public :: quat_mul, quat_conj, quat_norm, quat_normalize, quat_to_matrix, quat_from_matrix, &
            quat_rotate, quat_rotate_inverse, quat_exp, quat_log, quat_identity, quat_angle_between

  real(dp), parameter :: quat_identity(4) = [1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp]

contains

  pure function quat_mul(a, b) result(c)
    real(dp), intent(in) :: a(4), b(4)
    real(dp) :: c(4)
    c(1) = a(1)*b(1) - a(2)*b(2) - a(3)*b(3) - a(4)*b(4)
    c(2) = a(1)*b(2) + a(2)*b(1) + a(3)*b(4) - a(4)*b(3)
    c(3) = a(1)*b(3) - a(2)*b(4) + a(3)*b(1) + a(4)*b(2)
    c(4) = a(1)*b(4) + a(2)*b(3) - a(3)*b(2) + a(4)*b(1)
  end function quat_mul

  pure function quat_conj(q) result(c)
    real(dp), intent(in) :: q(4)
    real(dp) :: c(4)
    c = [q(1), -q(2), -q(3), -q(4)]
  end function quat_conj

  pure real(dp) function quat_norm(q)
    real(dp), intent(in) :: q(4)
    quat_norm = norm2(q)
  end function quat_norm

  !> Unit quaternion with non-negative scalar part (q and -q are the same rotation; one
  !> canonical sign keeps outputs and comparisons stable).
  pure function quat_normalize(q) result(u)
    real(dp), intent(in) :: q(4)
    real(dp) :: u(4)
    u = q/norm2(q)
    if (u(1) < 0.0_dp) u = -u
  end function quat_normalize

  pure function quat_to_matrix(q) result(r)
    real(dp), intent(in) :: q(4)
    real(dp) :: r(3, 3)
    real(dp) :: w, x, y, z
    w = q(1); x = q(2); y = q(3); z = q(4)
    r(1, 1) = 1.0_dp - 2.0_dp*(y*y + z*z)
    r(1, 2) = 2.0_dp*(x*y - w*z)
    r(1, 3) = 2.0_dp*(x*z + w*y)
    r(2, 1) = 2.0_dp*(x*y + w*z)
    r(2, 2) = 1.0_dp - 2.0_dp*(x*x + z*z)
    r(2, 3) = 2.0_dp*(y*z - w*x)
    r(3, 1) = 2.0_dp*(x*z - w*y)
    r(3, 2) = 2.0_dp*(y*z + w*x)
    r(3, 3) = 1.0_dp - 2.0_dp*(x*x + y*y)
  end function quat_to_matrix

  !> Quaternion of a proper rotation matrix (Shepperd's method: pivot on the largest
  !> diagonal term so no square root of a small difference is taken).
  pure function quat_from_matrix(r) result(q)
    real(dp), intent(in) :: r(3, 3)
    real(dp) :: q(4)
    real(dp) :: trace, s
    trace = r(1, 1) + r(2, 2) + r(3, 3)
    if (trace >= r(1, 1) .and. trace >= r(2, 2) .and. trace >= r(3, 3)) then
      s = 2.0_dp*sqrt(1.0_dp + trace)
      q = [0.25_dp*s, (r(3, 2) - r(2, 3))/s, (r(1, 3) - r(3, 1))/s, (r(2, 1) - r(1, 2))/s]
    else if (r(1, 1) >= r(2, 2) .and. r(1, 1) >= r(3, 3)) then
      s = 2.0_dp*sqrt(1.0_dp + r(1, 1) - r(2, 2) - r(3, 3))
      q = [(r(3, 2) - r(2, 3))/s, 0.25_dp*s, (r(1, 2) + r(2, 1))/s, (r(1, 3) + r(3, 1))/s]
    else if (r(2, 2) >= r(3, 3)) then
      s = 2.0_dp*sqrt(1.0_dp + r(2, 2) - r(1, 1) - r(3, 3))
      q = [(r(1, 3) - r(3, 1))/s, (r(1, 2) + r(2, 1))/s, 0.25_dp*s, (r(2, 3) + r(3, 2))/s]
    else
      s = 2.0_dp*sqrt(1.0_dp + r(3, 3) - r(1, 1) - r(2, 2))
      q = [(r(2, 1) - r(1, 2))/s, (r(1, 3) + r(3, 1))/s, (r(2, 3) + r(3, 2))/s, 0.25_dp*s]
    end if
    q = quat_normalize(q)
  end function quat_from_matrix

  !> R(q) v without forming the matrix.
  pure function quat_rotate(q, v) result(w)
    real(dp), intent(in) :: q(4), v(3)
    real(dp) :: w(3), t(3)
    t = 2.0_dp*cross(q(2:4), v)
    w = v + q(1)*t + cross(q(2:4), t)
  end function quat_rotate

  !> R(q)^T v.
  pure function quat_rotate_inverse(q, v) result(w)
    real(dp), intent(in) :: q(4), v(3)
    real(dp) :: w(3)
    w = quat_rotate(quat_conj(q), v)
  end function quat_rotate_inverse

  !> Quaternion of the rotation by the rotation vector theta (angle |theta| about its axis).
  !> Uses sin(x/2)/x by its series near 0 so tiny rotations keep full relative accuracy.
  pure function quat_exp(theta) result(q)
    real(dp), intent(in) :: theta(3)
    real(dp) :: q(4)
    real(dp) :: angle, half, s
    angle = norm2(theta)
    half = 0.5_dp*angle
    if (angle < 1.0e-4_dp) then
      s = 0.5_dp*(1.0_dp - half*half/6.0_dp*(1.0_dp - half*half/20.0_dp))
    else
      s = sin(half)/angle
    end if
    q = [cos(half), s*theta(1), s*theta(2), s*theta(3)]
  end function quat_exp

  !> Rotation vector of a unit quaternion (inverse of quat_exp, angle in [0, pi]).
  pure function quat_log(q) result(theta)
    real(dp), intent(in) :: q(4)
    real(dp) :: theta(3)
    real(dp) :: u(4), vnorm, angle
    u = quat_normalize(q)
    vnorm = norm2(u(2:4))
    if (vnorm < 1.0e-300_dp) then
      theta = 0.0_dp
      return
    end if
    angle = 2.0_dp*atan2(vnorm, u(1))
    theta = angle*u(2:4)/vnorm
  end function quat_log

  !> Angle [rad] of the rotation taking orientation a to orientation b.
  pure real(dp) function quat_angle_between(a, b)
    real(dp), intent(in) :: a(4), b(4)
    quat_angle_between = norm2(quat_log(quat_mul(b, quat_conj(a))))
  end function quat_angle_between

end module quaternion
