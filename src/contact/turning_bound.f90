!> A directional, second-order bound on how far two turning convex bodies can close along a
!> fixed direction, for conservative advancement (time_of_contact). The first-order bound of
!> advancement_bound lets every point of a turning body move at Omega R along n, whatever
!> the direction of the rotation and whichever part of the body faces the other: for a cube
!> approaching on a corner, the corner's own speed along n is nearly zero, while Omega R
!> says it closes at full speed, so each advancement iterate moves little.
!>
!> Derivation. Fix a unit n (from A to B) at time t and let tau >= 0 run over the interval.
!> For ANY two sets the distance is at least their separation along n:
!>     gap(t + tau) >= sep(t + tau) = min_{q in B} n.q - max_{p in A} n.p.
!> A body is the convex hull of its vertices r_k (body frame, fixed) swept by a sphere of
!> radius r_s (analytic spheres: one vertex at the centre; meshes: r_s = 0), so
!>     max_{p in A} n.p(t + tau) = n.x_A(t + tau) + r_s + max_k n.rho_k(t + tau),
!> rho_k = R_A r_k the vertex relative to the centre of mass. Translation is the
!> propagator's parabola: n.(x_A(t + tau) - x_A(t)) = n.v_A tau + n.a_A tau^2/2 exactly.
!> Rotation: d/dtau (n.rho_k) = g_k = n.(w x rho_k), and
!>     g_k' = n.(alpha x rho_k + w x (w x rho_k)),   |g_k'| <= (|alpha| + |w|^2) |rho_k|,
!> with |w| <= Omega for all tau (torque-free: advancement_bound's angular_speed_bound) and
!> |alpha| <= A (below), so over the whole interval
!>     n.rho_k(t + tau) <= n.rho_k(t) + g_k(t) tau + K tau^2/2,   K = (A + Omega^2) R,
!> R the largest |r_k|. With c_k = n.rho_k(t) - max_l n.rho_l(t) <= 0 and s_k = g_k(t),
!>     max_p n.p(t + tau) - max_p n.p(t) <= n.v_A tau + n.a_A tau^2/2 + P_A(tau),
!>     P_A(tau) = max_k (c_k + s_k tau) + K_A tau^2/2,
!> and the same for B's lowest point along n (its vertices seen along -n). Hence
!>     sep(t + tau) >= sep(t) - closing(tau),
!>     closing(tau) = n.(v_A - v_B) tau + n.(a_A - a_B) tau^2/2 + P_A(tau) + P_B(tau).
!> closing is convex in tau and 0 at tau = 0; it is the largest of the parabolas of the
!> vertex pairs (k, j), (c_k + c_j) + (n.(v_A - v_B) + s_k + s_j) tau + acc tau^2/2 with
!> acc = n.(a_A - a_B) + K_A + K_B, so the first time it reaches sep(t) - above is the
!> smallest of their roots (time_to_close of each, gap sep - above - c_k - c_j). Vertices
!> far behind the supporting plane (c_k << 0) do not count until they could pass it, and
!> the supporting vertices count only with their own speed along n: for convex pairs, where
!> sep(t) is the gap (the closest-point normal), that is the exact first-order closing rate.
!> Pruning: with (k0, j0) the supporting vertices, closing >= their parabola, whose root
!> T0 bounds the answer; a vertex whose line stays below its support vertex's on [0, T]
!> (T = min(T0, horizon)), c_k + (s_k - s_k0) T <= 0, is never on the envelope there.
!>
!> Angular acceleration of torque-free rotation (body frame): alpha_i = c_i w_j w_k with
!> c_i = (I_j - I_k)/I_i over the cyclic (i, j, k), so |alpha|^2 <= max c_i^2 (w_1^2 w_2^2 +
!> w_2^2 w_3^2 + w_3^2 w_1^2) <= max c_i^2 |w|^4/3: A = max|c_i| Omega^2/sqrt(3) (zero for
!> a cube or a sphere, whose w is constant).
!> The bound is for the exact propagator's motion (free_flight's 'exact' mode): it holds for
!> the true torque-free rotation, which that propagator evaluates to round-off.
module turning_bound
  use kinds, only: dp
  use quaternion, only: quat_rotate_inverse
  use advancement_bound, only: closing_bound_t, time_to_close, angular_speed_bound
  implicit none
  private
  public :: turning_body_t, turning_body, angular_acceleration_bound, body_lines, directional_time

  !> One body at the time the bound starts: its pose, velocities and turning curvature.
  type :: turning_body_t
    real(dp) :: x(3) = 0.0_dp                              !< centre of mass (world) [m]
    real(dp) :: q(4) = [1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp]   !< orientation, body to world
    real(dp) :: w(3) = 0.0_dp                              !< angular velocity (world) [rad/s]
    real(dp) :: v(3) = 0.0_dp                              !< velocity of the centre [m/s]
    real(dp) :: a(3) = 0.0_dp                              !< acceleration of the centre [m/s^2]
    real(dp) :: curvature = 0.0_dp   !< K = (A + Omega^2) R over the interval [m/s^2]
    real(dp) :: radius = 0.0_dp      !< radius swept around the vertices (analytic sphere) [m]
  end type turning_body_t

  !> Vertex pairs tried one by one; above this the vertices' largest speed is used instead.
  integer, parameter :: max_vertex_pairs = 256

contains

  !> Bound A on |alpha| for all time of a torque-free body with principal moments `inertia`
  !> whose angular speed never exceeds omega (see the header).
  pure real(dp) function angular_acceleration_bound(inertia, omega) result(accel)
    real(dp), intent(in) :: inertia(3), omega
    real(dp) :: c(3)
    c(1) = (inertia(2) - inertia(3))/inertia(1)
    c(2) = (inertia(3) - inertia(1))/inertia(2)
    c(3) = (inertia(1) - inertia(2))/inertia(3)
    accel = maxval(abs(c))*omega**2/sqrt(3.0_dp)
  end function angular_acceleration_bound

  !> The body's state at the bound's start, with its curvature K = (A + Omega^2) R from the
  !> angular speed bound of its body-frame angular velocity (1e-12 relative slack: the
  !> propagator conserves T to round-off only). reach: largest |r_k| (0 for a sphere).
  pure function turning_body(x, q, w, v, a, inertia, reach, radius) result(body)
    real(dp), intent(in) :: x(3), q(4), w(3), v(3), a(3), inertia(3), reach, radius
    type(turning_body_t) :: body
    real(dp) :: omega
    body%x = x
    body%q = q
    body%w = w
    body%v = v
    body%a = a
    body%radius = radius
    omega = (1.0_dp + 1.0e-12_dp)*angular_speed_bound(inertia, quat_rotate_inverse(q, w))
    body%curvature = 0.0_dp
    if (reach > 0.0_dp .and. omega > 0.0_dp) &
      body%curvature = (angular_acceleration_bound(inertia, omega) + omega**2)*reach
  end function turning_body

  !> The body's vertex lines along the unit direction m: offset(k) = m.rho_k - max_l m.rho_l
  !> (<= 0, 0 at a supporting vertex), slope(k) = m.(w x rho_k); support = the body's extent
  !> along m from its centre, max_k m.rho_k + radius. Works in the body frame:
  !> m.rho_k = (R^T m).r_k and m.(w x rho_k) = rho_k.(m x w) = (R^T (m x w)).r_k.
  pure subroutine body_lines(body, nodes, m, offset, slope, support)
    type(turning_body_t), intent(in) :: body
    real(dp), intent(in) :: nodes(:, :), m(3)
    real(dp), intent(out) :: offset(:), slope(:), support
    real(dp) :: m_body(3), u_body(3)
    integer :: k
    m_body = quat_rotate_inverse(body%q, m)
    u_body = quat_rotate_inverse(body%q, cross(m, body%w))
    do k = 1, size(nodes, 2)
      offset(k) = dot_product(m_body, nodes(:, k))
      slope(k) = dot_product(u_body, nodes(:, k))
    end do
    support = maxval(offset)
    offset = offset - support
    support = support + body%radius
  end subroutine body_lines

  !> Earliest tau in [0, horizon] at which the separation of A and B along the unit n (from
  !> A to B) may fall to `above` [m] (see the header); >= horizon when it cannot before the
  !> horizon, 0 when it is there already. nodes: each body's vertices in its body frame (a
  !> sphere: one column of zeros, radius in body%radius).
  pure real(dp) function directional_time(body_a, nodes_a, body_b, nodes_b, n, above, horizon) result(dt)
    type(turning_body_t), intent(in) :: body_a, body_b
    real(dp), intent(in) :: nodes_a(:, :), nodes_b(:, :), n(3), above, horizon
    real(dp) :: c_a(size(nodes_a, 2)), s_a(size(nodes_a, 2)), c_b(size(nodes_b, 2)), s_b(size(nodes_b, 2))
    integer :: keep_a(size(nodes_a, 2)), keep_b(size(nodes_b, 2))
    real(dp) :: support_a, support_b, sep, room, rate0, t_end
    type(closing_bound_t) :: bound
    integer :: k0, j0, na, nb, k, j
    call body_lines(body_a, nodes_a, n, c_a, s_a, support_a)
    call body_lines(body_b, nodes_b, -n, c_b, s_b, support_b)
    sep = dot_product(n, body_b%x - body_a%x) - support_a - support_b
    room = sep - above
    dt = 0.0_dp
    if (.not. (room > 0.0_dp)) return
    rate0 = dot_product(n, body_a%v - body_b%v)
    bound%acceleration = dot_product(n, body_a%a - body_b%a) + body_a%curvature + body_b%curvature
    k0 = support_vertex(c_a, s_a)
    j0 = support_vertex(c_b, s_b)
    ! the supporting vertices' parabola: the answer is no later than its root
    bound%rate = rate0 + s_a(k0) + s_b(j0)
    t_end = min(horizon, time_to_close(bound, room))
    call prune(c_a, s_a, k0, t_end, keep_a, na)
    call prune(c_b, s_b, j0, t_end, keep_b, nb)
    if (na*nb > max_vertex_pairs) then
      ! many vertices near the supporting planes (a fine mesh): c <= 0, so their largest
      ! speeds bound both envelopes
      bound%rate = rate0 + maxval(s_a(keep_a(1:na))) + maxval(s_b(keep_b(1:nb)))
      dt = time_to_close(bound, room)
      return
    end if
    dt = huge(1.0_dp)
    do k = 1, na
      do j = 1, nb
        bound%rate = rate0 + s_a(keep_a(k)) + s_b(keep_b(j))
        dt = min(dt, time_to_close(bound, room - c_a(keep_a(k)) - c_b(keep_b(j))))
      end do
    end do
  contains
    !> A vertex on the supporting plane (offset 0), the fastest along m of those.
    pure integer function support_vertex(c, s) result(k_best)
      real(dp), intent(in) :: c(:), s(:)
      integer :: k
      k_best = 1
      do k = 2, size(c)
        if (c(k) > c(k_best) .or. (c(k) == c(k_best) .and. s(k) > s(k_best))) k_best = k
      end do
    end function support_vertex

    !> The vertices whose line rises above the supporting vertex's before t_end (and it).
    pure subroutine prune(c, s, k_sup, t_stop, keep, n_keep)
      real(dp), intent(in) :: c(:), s(:), t_stop
      integer, intent(in) :: k_sup
      integer, intent(out) :: keep(:), n_keep
      integer :: k
      n_keep = 1
      keep(1) = k_sup
      do k = 1, size(c)
        if (k == k_sup) cycle
        if (c(k) + (s(k) - s(k_sup))*t_stop > 0.0_dp) then
          n_keep = n_keep + 1
          keep(n_keep) = k
        end if
      end do
    end subroutine prune
  end function directional_time

  pure function cross(a, b) result(c)
    real(dp), intent(in) :: a(3), b(3)
    real(dp) :: c(3)
    c = [a(2)*b(3) - a(3)*b(2), a(3)*b(1) - a(1)*b(3), a(1)*b(2) - a(2)*b(1)]
  end function cross

end module turning_bound
