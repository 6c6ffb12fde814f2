!> Turns the validated deck into shapes and bodies: one shape per distinct geometry (shared
!> by every copy), then every body of every &body group with its lattice copies and jitter.
!> Bodies get global ids in deck order, copies in lattice order (i fastest), so the same
!> deck gives the same ids on any number of ranks; each rank keeps the ids it owns.
module body_builder
  use kinds, only: dp, i8
  use error_status, only: error_t, ERR_INPUT, ERR_MESH
  use string_utils, only: str
  use quaternion, only: quat_mul, quat_exp, quat_normalize, quat_rotate, quat_rotate_inverse, quat_to_matrix
  use vector_ops, only: cross
  use random_stream, only: random_stream_t
  use mesh, only: mesh_t
  use mesh_io, only: read_mesh_file
  use mesh_topology, only: build_mesh_topology, is_convex
  use shape, only: shape_t, shape_library_t, SHAPE_SPHERE
  use shape_builders, only: box_mesh, cylinder_mesh, tetrahedron_mesh, torus_mesh, l_shape_mesh
  use shape_factory, only: make_sphere_shape, make_mesh_shape
  use mass_properties, only: inertia_defect
  use input_config, only: deck_t, body_spec_t
  use body_state, only: bodies_t
  use contact_material, only: material_table_t
  implicit none
  private
  public :: build_shapes, build_bodies, count_bodies, build_materials

contains

  !> The pair materials of a deck: restitution and friction per &body group, -1 (unset)
  !> meaning the &contact value.
  subroutine build_materials(deck, materials)
    type(deck_t), intent(in) :: deck
    type(material_table_t), intent(out) :: materials
    real(dp), allocatable :: restitution(:), friction(:)
    allocate (restitution(0), friction(0))
    if (allocated(deck%bodies)) then
      restitution = deck%bodies(1:deck%n_bodies)%restitution
      friction = deck%bodies(1:deck%n_bodies)%friction
    end if
    call materials%init(deck%contact, restitution, friction)
  end subroutine build_materials

  !> Total number of bodies the deck describes (all lattice copies of all groups).
  pure integer(i8) function count_bodies(deck)
    type(deck_t), intent(in) :: deck
    integer :: k
    count_bodies = 0
    do k = 1, deck%n_bodies
      count_bodies = count_bodies + product(int(deck%bodies(k)%copies, i8))
    end do
  end function count_bodies

  !> Builds every distinct shape once; shape_of_group(k) is the library index of group k.
  subroutine build_shapes(deck, shapes, shape_of_group, err)
    type(deck_t), intent(in) :: deck
    type(shape_library_t), intent(inout) :: shapes
    integer, allocatable, intent(out) :: shape_of_group(:)
    type(error_t), intent(inout) :: err
    type(shape_t) :: new_shape
    type(mesh_t) :: m
    character(len=:), allocatable :: label, where
    integer :: k, index
    allocate (shape_of_group(deck%n_bodies))
    do k = 1, deck%n_bodies
      associate (spec => deck%bodies(k))
        where = deck%path//':'//str(spec%line)//': &body #'//str(k)//" '"//trim(spec%name)//"': "
        label = shape_label(spec)
        index = shapes%find(label)
        if (index == 0) then
          select case (trim(spec%shape))
          case ('sphere')
            call make_sphere_shape(spec%radius, new_shape)
          case ('box')
            call box_mesh(spec%size, m)
          case ('cylinder')
            call cylinder_mesh(spec%radius, spec%size(3), spec%segments, m)
          case ('tetrahedron')
            call tetrahedron_mesh(spec%size(1), m)
          case ('torus')
            call torus_mesh(spec%radius, spec%minor_radius, spec%segments, spec%tube_segments, m)
          case ('l_prism')
            call l_shape_mesh(spec%size, spec%thickness, m)
          case ('mesh')
            call read_mesh_file(trim(spec%mesh_file), m, err, scale=spec%scale)
          case default
            call err%set(ERR_INPUT, "unknown shape '"//trim(spec%shape)//"'")
          end select
          ! Built-in meshes come without topology; read_mesh_file builds its own.
          if (err%ok() .and. spec%shape /= 'sphere' .and. spec%shape /= 'mesh') call build_mesh_topology(m, err)
          if (err%ok() .and. spec%shape /= 'sphere') call make_mesh_shape(m, label, new_shape, err)
          ! The shape holds its own copy of the mesh: this one is not needed any more (for a
          ! 10^6-face mesh some 100 MB less at the peak of the tree build below).
          call m%free()
          if (err%ok() .and. spec%shape /= 'sphere') new_shape%convex = is_convex(new_shape%mesh)
          if (err%failed()) then
            call err%prefix(where)
            return
          end if
          new_shape%label = label
          call shapes%add(new_shape, index)
          call new_shape%mesh%free()
          ! One SKD-tree per shape, shared by every body of that shape, built in place in
          ! the library (built in new_shape, add would copy it: 300 MB more for 10^6 faces).
          if (shapes%shapes(index)%kind /= SHAPE_SPHERE) then
            call shapes%shapes(index)%tree%build(shapes%shapes(index)%mesh, err)
            if (err%failed()) then
              call err%prefix(where)
              return
            end if
          end if
        end if
        shape_of_group(k) = index
      end associate
    end do
  end subroutine build_shapes

  !> Identical descriptions give identical labels, so they share one shape.
  function shape_label(spec) result(label)
    type(body_spec_t), intent(in) :: spec
    character(len=:), allocatable :: label
    character(len=200) :: buffer
    select case (trim(spec%shape))
    case ('sphere')
      write (buffer, '(a,es23.16)') 'sphere r=', spec%radius
    case ('box')
      write (buffer, '(a,3es24.16)') 'box', spec%size
    case ('cylinder')
      write (buffer, '(a,2es24.16,a,i0)') 'cylinder', spec%radius, spec%size(3), ' n=', spec%segments
    case ('tetrahedron')
      write (buffer, '(a,es23.16)') 'tetrahedron a=', spec%size(1)
    case ('torus')
      write (buffer, '(a,2es24.16,a,i0,a,i0)') 'torus', spec%radius, spec%minor_radius, ' n=', spec%segments, &
        ' x ', spec%tube_segments
    case ('l_prism')
      write (buffer, '(a,3es24.16,a,es23.16)') 'l_prism', spec%size, ' t=', spec%thickness
    case default
      write (buffer, '(a,es23.16)') 'scale=', spec%scale
      label = 'mesh '//trim(spec%mesh_file)//' '//trim(buffer)
      return
    end select
    label = trim(buffer)
  end function shape_label

  !> Fills `bodies` with the bodies this rank owns (global ids first..last).
  subroutine build_bodies(deck, shapes, shape_of_group, gravity, first, last, bodies, err)
    type(deck_t), intent(in) :: deck
    type(shape_library_t), intent(in) :: shapes
    integer, intent(in) :: shape_of_group(:)
    real(dp), intent(in) :: gravity(3)
    integer(i8), intent(in) :: first, last
    type(bodies_t), intent(inout) :: bodies
    type(error_t), intent(inout) :: err
    type(random_stream_t) :: stream
    integer(i8) :: gid
    integer :: k, i, j, l, n
    real(dp) :: position(3), orientation(4), velocity(3), jitter_axis(3), density, moments(3)
    call bodies%allocate(int(max(0_i8, last - first + 1)))
    gid = 0
    n = 0
    do k = 1, deck%n_bodies
      associate (spec => deck%bodies(k), s => shapes%shapes(shape_of_group(k)))
        if (spec%mass > 0.0_dp) then
          density = spec%mass/s%volume
        else
          density = spec%density
        end if
        call principal_moments(spec, s, density, moments, err)
        ! Fixed bodies never turn (their inertia is not used): only moving ones are checked.
        if (err%ok() .and. .not. spec%fixed) call check_moments(spec, moments, err)
        if (err%failed()) then
          call err%prefix(deck%path//':'//str(spec%line)//': &body #'//str(k)//" '"//trim(spec%name)//"': ")
          return
        end if
        if (spec%seed /= 0) call stream%init(spec%seed)
        do l = 1, spec%copies(3)
          do j = 1, spec%copies(2)
            do i = 1, spec%copies(1)
              gid = gid + 1
              position = spec%position + [real(i - 1, dp), real(j - 1, dp), real(l - 1, dp)]*spec%spacing
              orientation = spec%orientation
              velocity = spec%velocity
              ! Every copy draws its jitter, owned or not, so a body's jitter does not
              ! depend on the number of ranks.
              if (spec%seed /= 0) then
                position = position + [stream%symmetric(spec%jitter_position), &
                                       stream%symmetric(spec%jitter_position), stream%symmetric(spec%jitter_position)]
                jitter_axis = stream%unit_vector()
                orientation = quat_normalize(quat_mul(quat_exp(stream%uniform()*spec%jitter_angle*jitter_axis), &
                                                      orientation))
                velocity = velocity + [stream%symmetric(spec%jitter_velocity), &
                                       stream%symmetric(spec%jitter_velocity), stream%symmetric(spec%jitter_velocity)]
              end if
              if (gid < first .or. gid > last) cycle
              n = n + 1
              call place_body(bodies, n, gid, k, shape_of_group(k), s, spec%fixed, density, moments, position, &
                              orientation, velocity, spec%angular_velocity, gravity)
            end do
          end do
        end do
      end associate
    end do
    bodies%n_owned = n
    if (n /= last - first + 1) call err%set(ERR_INPUT, 'internal: built '//str(n)//' bodies, expected '// &
                                            str(last - first + 1))
  end subroutine build_bodies

  !> Principal moments of a group's bodies [kg m^2]: the uniform solid's, or the deck's
  !> `inertia` (given about the shape's own axes) expressed in the shape's principal frame,
  !> where it must be diagonal too (true for boxes, cylinders, spheres, tetrahedra, tori,
  !> symmetric meshes; not for an L prism, whose own x, y axes are not principal).
  subroutine principal_moments(spec, s, density, moments, err)
    type(body_spec_t), intent(in) :: spec
    type(shape_t), intent(in) :: s
    real(dp), intent(in) :: density
    real(dp), intent(out) :: moments(3)
    type(error_t), intent(inout) :: err
    real(dp) :: r(3, 3), j(3, 3)
    integer :: k
    if (any(spec%inertia <= 0.0_dp)) then
      moments = density*s%unit_inertia
      return
    end if
    r = quat_to_matrix(s%q_principal)
    j = matmul(transpose(r), matmul(reshape([spec%inertia(1), 0.0_dp, 0.0_dp, 0.0_dp, spec%inertia(2), 0.0_dp, &
                                             0.0_dp, 0.0_dp, spec%inertia(3)], [3, 3]), r))
    do k = 1, 3
      moments(k) = j(k, k)
    end do
    ! The principal axes of the solid are only defined up to rotations within equal
    ! moments, so off-diagonal terms above round-off mean the deck's axes are not its own.
    if (maxval(abs(j - diagonal(moments))) > 1.0e-9_dp*maxval(moments)) then
      call err%set(ERR_INPUT, 'inertia: the shape''s inertia tensor is not diagonal in its own axes, so '// &
                   'three moments about them do not define the body''s inertia')
    end if
  contains
    pure function diagonal(d) result(m)
      real(dp), intent(in) :: d(3)
      real(dp) :: m(3, 3)
      m = 0.0_dp
      m(1, 1) = d(1); m(2, 2) = d(2); m(3, 3) = d(3)
    end function diagonal
  end subroutine principal_moments

  !> Refuses moments no rigid body has (mass_properties' inertia_defect), saying where they
  !> come from: the deck's inertia, the mesh file, or the built-in shape.
  subroutine check_moments(spec, moments, err)
    type(body_spec_t), intent(in) :: spec
    real(dp), intent(in) :: moments(3)
    type(error_t), intent(inout) :: err
    character(len=:), allocatable :: defect, origin
    character(len=100) :: values
    defect = inertia_defect(moments)
    if (len(defect) == 0) return
    write (values, '(3(1pg0.9,:,", "))') moments
    if (all(spec%inertia > 0.0_dp)) then
      origin = 'inertia = '//str(spec%inertia(1))//', '//str(spec%inertia(2))//', '//str(spec%inertia(3))// &
               ' kg m^2 (the deck''s)'
    else if (trim(spec%shape) == 'mesh') then
      origin = "mesh '"//trim(spec%mesh_file)//"' (its shells may count volume negatively: an inward-facing "// &
               'shell outside the others, or shells oriented against each other)'
    else
      origin = "shape '"//trim(spec%shape)//"'"
    end if
    call err%set(ERR_MESH, 'principal moments '//trim(values)//' kg m^2 from '//origin// &
                 ' are not a rigid body''s inertia: '//defect)
    if (all(spec%inertia > 0.0_dp)) err%code = ERR_INPUT
  end subroutine check_moments

  !> Sets body n from the user's description: the user orientation rotates the shape's own
  !> frame into the world; internally the body is held in the shape's principal frame.
  subroutine place_body(bodies, n, gid, group, shape_index, s, fixed, density, moments, position, orientation, &
                        velocity, angular_velocity, gravity)
    type(bodies_t), intent(inout) :: bodies
    integer, intent(in) :: n, group, shape_index
    integer(i8), intent(in) :: gid
    type(shape_t), intent(in) :: s
    logical, intent(in) :: fixed
    real(dp), intent(in) :: density, moments(3), position(3), orientation(4), velocity(3), angular_velocity(3), &
                            gravity(3)
    real(dp) :: jw(3), wb(3)
    bodies%gid(n) = gid
    bodies%group_id(n) = group
    bodies%shape_id(n) = shape_index
    bodies%fixed(n) = fixed
    bodies%x(:, n) = position
    bodies%q(:, n) = quat_normalize(quat_mul(orientation, s%q_principal))
    if (fixed) then
      bodies%mass(n) = max(density, 0.0_dp)*s%volume
      bodies%inertia(:, n) = max(density, 0.0_dp)*s%unit_inertia
      bodies%inv_mass(n) = 0.0_dp
      bodies%inv_inertia(:, n) = 0.0_dp
      bodies%v(:, n) = 0.0_dp
      bodies%w(:, n) = 0.0_dp
      bodies%a(:, n) = 0.0_dp
      bodies%alpha(:, n) = 0.0_dp
      return
    end if
    bodies%mass(n) = density*s%volume
    bodies%inertia(:, n) = moments
    bodies%inv_mass(n) = 1.0_dp/bodies%mass(n)
    bodies%inv_inertia(:, n) = 1.0_dp/bodies%inertia(:, n)
    bodies%v(:, n) = velocity
    bodies%w(:, n) = angular_velocity
    bodies%a(:, n) = gravity
    ! Euler's equations at t0, torque-free: J alpha = -w x (J w), in the body frame.
    wb = quat_rotate_inverse(bodies%q(:, n), angular_velocity)
    jw = bodies%inertia(:, n)*wb
    bodies%alpha(:, n) = quat_rotate(bodies%q(:, n), -cross(wb, jw)*bodies%inv_inertia(:, n))
    if (s%kind == SHAPE_SPHERE) bodies%alpha(:, n) = 0.0_dp
  end subroutine place_body

end module body_builder
