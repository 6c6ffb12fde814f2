!> The contact pass's solves (resting_contact): static friction held exactly on an incline
!> below its friction angle (the sticking solve), sliding kept above it, and a speculative
!> contact (allowed approach speed) in the projected Gauss-Seidel path.
program test_contact_pass
  use kinds, only: dp, i8
  use error_status, only: error_t
  use quaternion, only: quat_exp, quat_rotate
  use body_state, only: bodies_t
  use input_config, only: integrator_config_t
  use free_flight, only: free_flight_t
  use impulse_solver, only: contact_t, normal_velocity
  use resting_contact, only: resting_contact_t
  use assertions
  implicit none
  real(dp), parameter :: g(3) = [0.0_dp, 0.0_dp, -9.81_dp], h = 1.0e-2_dp, edge = 0.1_dp
  real(dp), parameter :: pi = acos(-1.0_dp)
  type(bodies_t) :: bodies
  type(free_flight_t) :: flight
  type(integrator_config_t) :: config
  type(resting_contact_t) :: pass
  type(contact_t), allocatable :: contacts(:)
  integer(i8), allocatable :: keys(:, :)
  type(error_t) :: err
  real(dp) :: down(3), speed, expected

  ! 1. A cube sliding down a 20 degree incline at 5 mm/s, mu = 0.5 > tan 20 = 0.364: the
  !    slope can hold it, so the pass stops it, exactly (the iterative solve alone leaves its
  !    tolerance, 1e-9 m/s, and more when it hits its sweep cap), through the sticking solve.
  call cube_on_incline(20.0_dp, 0.5_dp, 5.0e-3_dp)
  call pass%solve(bodies, flight, contacts, keys, size(contacts), h, g, err)
  call check(err%ok(), 'incline 20, mu 0.5: solve succeeded')
  call check(pass%stats%stuck == 1, 'incline 20, mu 0.5: held by the sticking solve')
  call check_close(norm2(bodies%v(:, 2)) + edge*norm2(bodies%w(:, 2)), 0.0_dp, 0.0_dp, &
                   'incline 20, mu 0.5: at rest to round-off', atol=1.0e-13_dp)
  ! The impulses carry the weight for the step and stop the slide: m (0 - v0) - m g h.
  call check_close_array(sum(pass%cache_force(:, 1:pass%n_cache), dim=2)*h, -5.0e-3_dp*down - g*h, 0.0_dp, &
                         'incline 20, mu 0.5: the contacts carry m g h and stop the slide', atol=1.0e-14_dp)

  ! 2. 30 degrees with mu = 0.3 < tan 30: it must slide on, with a = g (sin - mu cos) over
  !    the step (the sticking solve finds no impulses inside the cones and changes nothing).
  call cube_on_incline(30.0_dp, 0.3_dp, 5.0e-3_dp)
  pass%stats%stuck = 0
  call pass%solve(bodies, flight, contacts, keys, size(contacts), h, g, err)
  call check(pass%stats%stuck == 0, 'incline 30, mu 0.3: not stuck')
  speed = dot_product(bodies%v(:, 2), down)
  expected = 5.0e-3_dp + 9.81_dp*(sin(pi/6.0_dp) - 0.3_dp*cos(pi/6.0_dp))*h
  ! (projected Gauss-Seidel on one body converges to its 1e-9 m/s tolerance)
  call check_close(speed, expected, 0.0_dp, 'incline 30, mu 0.3: slides at v0 + g (sin - mu cos) h', atol=1.0e-8_dp)

  ! 3. A speculative contact: the cube 1 cm above a floor, falling at 3 m/s, may approach at
  !    0.5 m/s (the speed that closes the gap in the step): the pass leaves it exactly that.
  call cube_on_incline(0.0_dp, 0.5_dp, 0.0_dp)
  bodies%v(:, 2) = [0.0_dp, 0.0_dp, -3.0_dp]
  contacts%allowed_approach = 0.5_dp
  call pass%solve(bodies, flight, contacts, keys, size(contacts), h, g, err)
  call check_close(bodies%v(3, 2), -0.5_dp, 0.0_dp, 'speculative: approaches at the allowed speed', atol=1.0e-8_dp)
  call check(minval([normal_velocity(bodies, contacts(1)), normal_velocity(bodies, contacts(2)), &
                     normal_velocity(bodies, contacts(3)), normal_velocity(bodies, contacts(4))]) > -0.5_dp - 1.0e-8_dp, &
             'speculative: no corner faster than allowed')
  call test_finish()

contains

  !> Body 1: a fixed incline at theta degrees (its surface through the origin); body 2: a
  !> 1 kg cube of edge 0.1 m on it, moving down the slope at speed v0, with its four
  !> bottom corners as contacts (normal: the slope's, from 1 to 2), friction mu.
  subroutine cube_on_incline(theta_degrees, mu, v0)
    real(dp), intent(in) :: theta_degrees, mu, v0
    real(dp) :: theta, q(4), normal(3), corner(3)
    integer :: k
    theta = theta_degrees*pi/180.0_dp
    q = quat_exp([0.0_dp, theta, 0.0_dp])      ! the slope's frame: turned about y
    normal = quat_rotate(q, [0.0_dp, 0.0_dp, 1.0_dp])
    down = quat_rotate(q, [1.0_dp, 0.0_dp, 0.0_dp])
    if (down(3) > 0.0_dp) down = -down
    call bodies%allocate(2)
    bodies%n_owned = 2
    bodies%gid = [1_i8, 2_i8]
    bodies%fixed = [.true., .false.]
    bodies%mass = [0.0_dp, 1.0_dp]
    bodies%inv_mass = [0.0_dp, 1.0_dp]
    bodies%inertia(:, 2) = edge**2/6.0_dp
    bodies%inv_inertia(:, 1) = 0.0_dp
    bodies%inv_inertia(:, 2) = 6.0_dp/edge**2
    bodies%q(:, 1) = q
    bodies%q(:, 2) = q
    bodies%x(:, 1) = 0.0_dp
    bodies%x(:, 2) = 0.5_dp*edge*normal
    bodies%v = 0.0_dp
    bodies%w = 0.0_dp
    bodies%v(:, 2) = v0*down
    call flight%init(2, config)
    if (allocated(contacts)) deallocate (contacts, keys)
    allocate (contacts(4), keys(7, 4))
    do k = 1, 4
      corner = quat_rotate(q, [merge(0.5_dp, -0.5_dp, k <= 2)*edge, merge(0.5_dp, -0.5_dp, mod(k, 2) == 1)*edge, 0.0_dp])
      contacts(k) = contact_t(a=1, b=2, point=corner, normal=normal, friction=mu, gap=1.0e-5_dp)
      keys(:, k) = [1_i8, 2_i8, 1_i8, int(k, i8), 0_i8, 1_i8, 0_i8]
    end do
    call pass%forget()
  end subroutine cube_on_incline

end program test_contact_pass
