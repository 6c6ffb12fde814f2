!> A second-order lower bound on the gap of a pair, for pairs in or near contact whose
!> bodies turn (docs/contact.md, "The bound for turning bodies in contact").
!>
!> The first-order bound of conservative advancement lets any point of a turning body close
!> at Omega R: a tumbling cube resting on an edge at the contact band (gap ~ min_separation)
!> may then only advance min_separation/(Omega R), about 1e-5 s. Yet the contact points
!> themselves do not approach (the contact pass made their normal velocity >= 0); they can
!> only curve towards the other body, at second order in time.
!>
!> Bound: for any unit vector n and any two bodies, the gap is at least the separation of
!> their projections on n: gap >= min_{q in V} n.q - max_{p in P} n.p. Hold n fixed in the
!> frame of one body, P (the "plane body"), so that its support h_P = max_p n.(p - x_P) is
!> constant, and write the separation as the smallest of one smooth function per vertex q
!> of the other body V:
!>     f_q(t) = n(t).(x_V(t) + rho_q(t) - x_P(t)) - h_P,     rho_q = R_V(t) r_q.
!> Each f_q starts at its exact value and slope, and its second derivative is bounded over
!> the step by M (below), so f_q(t) >= f_q(0) + f_q'(0) t - M t^2/2; the pair cannot come
!> closer than `floor` before the first time one of these parabolas reaches it.
!>     f'' = n''.w + 2 n'.w' + n.w'',  w = x_V + rho_q - x_P
!>     |n'| <= Omega_P, |n''| <= A_P + Omega_P^2  (n turns with P)
!>     |w| <= |x_V - x_P| + R_V + |v_rel| h + |a_rel| h^2/2,  |w'| <= |v_rel| + |a_rel| h + Omega_V R_V
!>     n.w'' >= n.a_rel - (A_V + Omega_V^2) R_V   (|n.a_rel| when n turns)
!> Omega: the angular speed bound of torque-free rotation (advancement_bound); A: the
!> angular acceleration of torque-free rotation, |I^-1 ((I w) x w)| <= (I_max - I_min)/(2
!> I_min) Omega^2 (zero for a cube); translation is the propagator's exact parabola.
!> A static body or an analytic sphere makes the best plane body: its support does not
!> depend on how it turns, so n stays fixed in the world (Omega_P = A_P = 0). With the
!> closest-point normal, the bound starts at the exact gap for convex pairs; for non-convex
!> ones it may start lower (still safe, only less useful).
!> plane_time is the same bound from given states: conservative advancement also takes it at
!> each iterate (collision_stage_advance's oracle, with either body as P), where a face
!> turning under the other body's corner would make the fixed-direction bounds crawl.
module plane_bound
  use kinds, only: dp
  use shape, only: shape_t, shape_library_t, SHAPE_SPHERE
  use body_state, only: bodies_t
  use free_flight, only: free_flight_t
  use advancement_bound, only: angular_speed_bound, closing_bound_t, time_to_close
  use quaternion, only: quat_rotate, quat_rotate_inverse
  implicit none
  private
  public :: plane_safe_time, plane_time, plane_body_at

  !> One body as the bound needs it: its state where the bound starts and its turning.
  type, public :: plane_body_t
    real(dp) :: x(3) = 0.0_dp, q(4) = [1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp], w(3) = 0.0_dp
    real(dp) :: v(3) = 0.0_dp, a(3) = 0.0_dp
    logical :: world_fixed = .false.   !< static or an analytic sphere: its support turns with nothing
    real(dp) :: omega = 0.0_dp         !< angular speed bound [rad/s]
    real(dp) :: accel = 0.0_dp         !< angular acceleration bound [rad/s^2]
  end type plane_body_t

contains

  !> Time [s] from the step's start before which the gap of the pair (i, j) cannot fall
  !> below floor [m], nor below its separation along normal now if that is lower (a pair at
  !> the floor that recedes), from the separating direction normal (unit, from i to j); h
  !> [s] is the step the bound must hold over (huge when nothing closes; 0: no bound).
  function plane_safe_time(shapes, bodies, flight, gravity, i, j, normal, floor, h) result(t_safe)
    type(shape_library_t), intent(in) :: shapes
    type(bodies_t), intent(in) :: bodies
    type(free_flight_t), intent(in) :: flight
    real(dp), intent(in) :: gravity(3)
    integer, intent(in) :: i, j
    real(dp), intent(in) :: normal(3), floor, h
    real(dp) :: t_safe
    integer :: p, v
    real(dp) :: n(3)

    ! The plane body: static or a sphere if either is (n then stays fixed in the world),
    ! else the body with more vertices (its support is computed once, the other's per vertex).
    ! (A static body first: a large static mesh as V could start the bound below zero.)
    ! The bound needs the torque-free rotation the exact propagator makes.
    t_safe = 0.0_dp
    if (.not. flight%exact .and. .not. (world_fixed_support(i) .and. world_fixed_support(j))) return
    if (bodies%fixed(i)) then
      p = i; v = j; n = normal
    else if (bodies%fixed(j)) then
      p = j; v = i; n = -normal
    else if (world_fixed_support(i)) then
      p = i; v = j; n = normal
    else if (world_fixed_support(j)) then
      p = j; v = i; n = -normal
    else if (vertex_count(i) >= vertex_count(j)) then
      p = i; v = j; n = normal
    else
      p = j; v = i; n = -normal
    end if
    t_safe = plane_time(shapes%shapes(bodies%shape_id(p)), plane_body(p), shapes%shapes(bodies%shape_id(v)), &
                        plane_body(v), n, floor, h)
  contains
    logical function world_fixed_support(k)
      integer, intent(in) :: k
      world_fixed_support = bodies%fixed(k) .or. shapes%shapes(bodies%shape_id(k))%kind == SHAPE_SPHERE
    end function world_fixed_support

    integer function vertex_count(k)
      integer, intent(in) :: k
      vertex_count = size(shapes%shapes(bodies%shape_id(k))%mesh%nodes, 2)
    end function vertex_count

    !> Body k at the step's start.
    function plane_body(k) result(body)
      integer, intent(in) :: k
      type(plane_body_t) :: body
      body = plane_body_at(bodies%x(:, k), bodies%q(:, k), bodies%w(:, k), bodies%v(:, k), bodies%inertia(:, k), &
                           bodies%fixed(k), shapes%shapes(bodies%shape_id(k)))
      if (.not. bodies%fixed(k)) body%a = flight%acceleration(k, gravity)
    end function plane_body
  end function plane_safe_time

  !> The state the bound needs of one body (acceleration a: to be set by the caller).
  function plane_body_at(x, q, w, v, inertia, fixed, sh) result(body)
    real(dp), intent(in) :: x(3), q(4), w(3), v(3), inertia(3)
    logical, intent(in) :: fixed
    type(shape_t), intent(in) :: sh
    type(plane_body_t) :: body
    body%x = x
    body%q = q
    body%w = w
    body%v = v
    body%a = 0.0_dp
    body%world_fixed = fixed .or. sh%kind == SHAPE_SPHERE
    body%omega = 0.0_dp
    body%accel = 0.0_dp
    ! Angular speed bound over the step and the bound on the angular acceleration of
    ! torque-free rotation (1e-12 relative slack: T is conserved to round-off only).
    if (.not. body%world_fixed) then
      body%omega = (1.0_dp + 1.0e-12_dp)*angular_speed_bound(inertia, quat_rotate_inverse(q, w))
      body%accel = 0.5_dp*(maxval(inertia) - minval(inertia))/minval(inertia)*body%omega**2
    end if
  end function plane_body_at

  !> The bound with P the plane body, V the other and n the unit normal from P to V: the
  !> time before which the gap cannot fall below floor (see plane_safe_time). Both bodies
  !> at the time the bound starts; h: the interval it must hold over.
  function plane_time(shape_p, body_p, shape_v, body_v, n, floor, h) result(t_safe)
    type(shape_t), intent(in) :: shape_p, shape_v
    type(plane_body_t), intent(in) :: body_p, body_v
    real(dp), intent(in) :: n(3), floor, h
    real(dp) :: t_safe
    integer :: k
    real(dp) :: support, omega_p, accel_p, omega_v, accel_v, reach_v, v_rel(3), a_rel(3)
    real(dp) :: w(3), rho(3), n_dot(3), f0, slope, m, w0, w1, n_body(3)
    type(closing_bound_t) :: bound
    logical :: fixed_frame

    fixed_frame = body_p%world_fixed

    ! Support of P along n, relative to its centre of mass.
    if (shape_p%kind == SHAPE_SPHERE) then
      support = shape_p%radius
    else
      n_body = quat_rotate_inverse(body_p%q, n)
      support = maxval(matmul(n_body, shape_p%mesh%nodes))
    end if

    omega_p = 0.0_dp
    accel_p = 0.0_dp
    if (.not. fixed_frame) then
      omega_p = body_p%omega
      accel_p = body_p%accel
    end if
    omega_v = 0.0_dp
    accel_v = 0.0_dp
    reach_v = 0.0_dp
    if (.not. body_v%world_fixed) then
      omega_v = body_v%omega
      accel_v = body_v%accel
      reach_v = shape_v%bounding_radius
    end if
    v_rel = body_v%v - body_p%v
    a_rel = body_v%a - body_p%a
    w0 = norm2(body_v%x - body_p%x) + shape_v%bounding_radius + &
         norm2(v_rel)*h + 0.5_dp*norm2(a_rel)*h*h
    w1 = norm2(v_rel) + norm2(a_rel)*h + omega_v*reach_v
    ! -M: a lower bound on every f_q'' over the step.
    if (fixed_frame) then
      m = -dot_product(n, a_rel) + (accel_v + omega_v**2)*reach_v
    else
      m = (accel_p + omega_p**2)*w0 + 2.0_dp*omega_p*w1 + norm2(a_rel) + (accel_v + omega_v**2)*reach_v
    end if
    ! n' = w_P x n (zero when n is fixed in the world)
    n_dot = 0.0_dp
    if (.not. fixed_frame) n_dot = cross(body_p%w, n)
    bound%acceleration = m

    t_safe = huge(1.0_dp)
    if (shape_v%kind == SHAPE_SPHERE) then
      ! The sphere's nearest point along -n is x_V - r n whichever way it turns.
      w = body_v%x - body_p%x
      f0 = dot_product(n, w) - shape_v%radius - support
      slope = dot_product(n_dot, w) + dot_product(n, v_rel)
      t_safe = vertex_safe_time(f0, slope)
    else
      associate (nodes => shape_v%mesh%nodes)
        do k = 1, size(nodes, 2)
          rho = quat_rotate(body_v%q, nodes(:, k))
          w = body_v%x + rho - body_p%x
          f0 = dot_product(n, w) - support
          slope = dot_product(n_dot, w) + dot_product(n, v_rel + cross(body_v%w, rho))
          t_safe = min(t_safe, vertex_safe_time(f0, slope))
          if (t_safe == 0.0_dp) return
        end do
      end associate
    end if
  contains
    !> How long f(t) >= f0 + slope t - m t^2/2 stays at or above min(floor, f0) [s]: a
    !> vertex above the floor may close to it; one at or below it (a pair the distance
    !> correction could not open) may not come closer, which holds while it still recedes
    !> (f back at f0 at t = 2 slope/m).
    real(dp) function vertex_safe_time(f0, slope) result(t_q)
      real(dp), intent(in) :: f0, slope
      if (f0 > floor) then
        bound%rate = -slope
        t_q = time_to_close(bound, f0 - floor)
      else if (slope > 0.0_dp) then
        t_q = huge(1.0_dp)
        if (m > 0.0_dp) t_q = 2.0_dp*slope/m
      else
        t_q = 0.0_dp
      end if
    end function vertex_safe_time
  end function plane_time

  pure function cross(a, b) result(c)
    real(dp), intent(in) :: a(3), b(3)
    real(dp) :: c(3)
    c = [a(2)*b(3) - a(3)*b(2), a(3)*b(1) - a(1)*b(3), a(1)*b(2) - a(2)*b(1)]
  end function cross

end module plane_bound
