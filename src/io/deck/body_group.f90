!> The &body group of a deck (docs/input.md): one body, or a lattice of copies of it, with
!> its shape and the variables of that shape, mass, pose, motion, lattice, jitter, inertia
!> and material. Its variables, the namelist read with the defaults reset (for every
!> &body), its rules, and its text in the effective deck. Messages name the group by index
!> and name: &body #3 'ball'.
module body_group
  use kinds, only: dp, i8
  use constants, only: pi, unit_quaternion_tolerance
  use error_status, only: error_t
  use string_utils, only: str, lower, name_index
  use input_config, only: body_spec_t
  use namelist_source, only: DECK_AUTO, V_REAL, V_INTEGER, V_LOGICAL, V_CHARACTER, T_WORD, T_STRING, T_EQUALS, &
                             var_spec_t, token_t, source_t, group_t, group_input_t, open_group, tokenize, &
                             check_assignments, translate_read_error, require_finite, given, given_element, &
                             first_element_line, var_line, fail, fail_at, suggestion, real_text, &
                             put_real, put_integer, put_logical, put_text, put_note
  use deck_paths, only: resolve_path
  use deck_sink, only: deck_sink_t
  implicit none
  private
  public :: read_body_group, write_body_group

  type(body_spec_t), parameter :: body_default = body_spec_t()

  type(var_spec_t), parameter :: body_vars(26) = [ &
    var_spec_t('name', V_CHARACTER, 1, len(body_default%name)), &
    var_spec_t('shape', V_CHARACTER, 1, len(body_default%shape)), &
    var_spec_t('radius', V_REAL, 1, 0), var_spec_t('size', V_REAL, 3, 0), &
    var_spec_t('segments', V_INTEGER, 1, 0), var_spec_t('minor_radius', V_REAL, 1, 0), &
    var_spec_t('tube_segments', V_INTEGER, 1, 0), var_spec_t('thickness', V_REAL, 1, 0), &
    var_spec_t('mesh_file', V_CHARACTER, 1, len(body_default%mesh_file)), &
    var_spec_t('scale', V_REAL, 1, 0), var_spec_t('density', V_REAL, 1, 0), var_spec_t('mass', V_REAL, 1, 0), &
    var_spec_t('position', V_REAL, 3, 0), var_spec_t('orientation', V_REAL, 4, 0), &
    var_spec_t('velocity', V_REAL, 3, 0), var_spec_t('angular_velocity', V_REAL, 3, 0), &
    var_spec_t('fixed', V_LOGICAL, 1, 0), var_spec_t('copies', V_INTEGER, 3, 0), &
    var_spec_t('spacing', V_REAL, 3, 0), var_spec_t('seed', V_INTEGER, 1, 0), &
    var_spec_t('jitter_position', V_REAL, 1, 0), var_spec_t('jitter_angle', V_REAL, 1, 0), &
    var_spec_t('jitter_velocity', V_REAL, 1, 0), var_spec_t('inertia', V_REAL, 3, 0), &
    var_spec_t('restitution', V_REAL, 1, 0), var_spec_t('friction', V_REAL, 1, 0)]

  character(len=11), parameter :: shape_names(7) = [character(len=11) :: 'sphere', 'box', 'cylinder', &
    'tetrahedron', 'torus', 'l_prism', 'mesh']
  character(len=*), parameter :: known_shapes = 'sphere, box, cylinder, tetrahedron, torus, l_prism, mesh'

contains

  !> One &body: defaults reset (spec is intent(out)), read, then checked for its shape.
  subroutine read_body_group(src, group, index, folder, spec, err)
    type(source_t), intent(in) :: src
    type(group_t), intent(in) :: group
    integer, intent(in) :: index
    character(len=*), intent(in) :: folder
    type(body_spec_t), intent(out) :: spec
    type(error_t), intent(inout) :: err
    type(group_input_t) :: g
    type(token_t), allocatable :: tokens(:)
    integer :: n_tokens, i
    character(len=:), allocatable :: label_name

    call open_group(src, group, body_vars, '&body #'//str(index), g)
    call tokenize(g, tokens, n_tokens, err)
    if (err%failed()) return
    ! The name goes into every message, so find it before checking anything else.
    label_name = 'body'//str(index)
    do i = 1, n_tokens - 2
      if (tokens(i)%kind == T_WORD .and. tokens(i + 1)%kind == T_EQUALS .and. tokens(i + 2)%kind == T_STRING) then
        if (lower(tokens(i)%text) == 'name') label_name = trim(tokens(i + 2)%text)
      end if
    end do
    g%label = '&body #'//str(index)//' '''//label_name//''''
    call check_assignments(g, tokens, n_tokens, err)
    if (err%failed()) return
    call namelist_read_body(g, spec, err)
    if (err%failed()) return
    spec%line = group%first_line
    if (.not. given(g, 'name')) spec%name = 'body'//str(index)
    call check_body(g, folder, spec, err)
  end subroutine read_body_group

  !> The namelist READ of one &body into spec (which holds the defaults on entry).
  subroutine namelist_read_body(g, spec, err)
    type(group_input_t), intent(in) :: g
    type(body_spec_t), intent(inout) :: spec
    type(error_t), intent(inout) :: err
    character(len=len(spec%name)) :: name
    character(len=len(spec%shape)) :: shape
    character(len=len(spec%mesh_file)) :: mesh_file
    real(dp) :: radius, size(3), minor_radius, thickness, scale, density, mass, position(3), orientation(4), &
                velocity(3), angular_velocity(3), spacing(3), jitter_position, jitter_angle, jitter_velocity, &
                inertia(3), restitution, friction
    integer :: segments, tube_segments, copies(3), seed
    logical :: fixed
    integer :: ios
    character(len=512) :: msg
    namelist /body/ name, shape, radius, size, segments, minor_radius, tube_segments, thickness, mesh_file, &
      scale, density, mass, position, orientation, velocity, angular_velocity, fixed, copies, spacing, seed, &
      jitter_position, jitter_angle, jitter_velocity, inertia, restitution, friction

    name = spec%name
    shape = spec%shape
    radius = spec%radius
    size = spec%size
    segments = spec%segments
    minor_radius = spec%minor_radius
    tube_segments = spec%tube_segments
    thickness = spec%thickness
    mesh_file = spec%mesh_file
    scale = spec%scale
    density = spec%density
    mass = spec%mass
    position = spec%position
    orientation = spec%orientation
    velocity = spec%velocity
    angular_velocity = spec%angular_velocity
    fixed = spec%fixed
    copies = spec%copies
    spacing = spec%spacing
    seed = spec%seed
    jitter_position = spec%jitter_position
    jitter_angle = spec%jitter_angle
    jitter_velocity = spec%jitter_velocity
    inertia = spec%inertia
    restitution = spec%restitution
    friction = spec%friction
    msg = ''
    read (g%text, nml=body, iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call translate_read_error(g, ios, msg, err)
      return
    end if
    spec%name = name
    spec%shape = lower(adjustl(shape))
    spec%radius = radius
    spec%size = size
    spec%segments = segments
    spec%minor_radius = minor_radius
    spec%tube_segments = tube_segments
    spec%thickness = thickness
    spec%mesh_file = mesh_file
    spec%scale = scale
    spec%density = density
    spec%mass = mass
    spec%position = position
    spec%orientation = orientation
    spec%velocity = velocity
    spec%angular_velocity = angular_velocity
    spec%fixed = fixed
    spec%copies = copies
    spec%spacing = spacing
    spec%seed = seed
    spec%jitter_position = jitter_position
    spec%jitter_angle = jitter_angle
    spec%jitter_velocity = jitter_velocity
    spec%inertia = inertia
    spec%restitution = restitution
    spec%friction = friction
  end subroutine namelist_read_body

  !> inertia: auto (all -1) or three positive moments that a rigid body can have (each at
  !> most the sum of the other two), for a body with mass, not a fixed one.
  subroutine check_inertia(g, spec, err)
    type(group_input_t), intent(in) :: g
    type(body_spec_t), intent(in) :: spec
    type(error_t), intent(inout) :: err
    real(dp) :: moments(3)
    integer :: k
    moments = spec%inertia
    if (all(moments == DECK_AUTO)) return
    if (any(moments <= 0.0_dp)) then
      call fail(g, err, 'inertia', 'inertia needs three moments > 0 kg m^2 (or none, for the solid''s own)')
    else if (spec%fixed) then
      call fail(g, err, 'inertia', 'a fixed body never moves: inertia must not be given')
    else
      do k = 1, 3
        ! Each moment is sum of m (y^2 + z^2)-like terms: I_k <= I_i + I_j for any body
        ! (equality for a flat plate); round-off slack of 1e-12 relative.
        if (moments(k) > (sum(moments) - moments(k))*(1.0_dp + 1.0e-12_dp)) then
          call fail(g, err, 'inertia', 'inertia: no rigid body has a moment larger than the sum of the other two')
          return
        end if
      end do
    end if
  end subroutine check_inertia

  !> The rules of a &body (docs/input.md): shape and its variables, mass, orientation,
  !> motion of fixed bodies, lattice and jitter.
  subroutine check_body(g, folder, spec, err)
    type(group_input_t), intent(in) :: g
    character(len=*), intent(in) :: folder
    type(body_spec_t), intent(inout) :: spec
    type(error_t), intent(inout) :: err
    character(len=:), allocatable :: resolved, shape
    real(dp) :: norm
    integer :: axis
    logical :: exists
    character, parameter :: axis_name(3) = ['x', 'y', 'z']

    call require_finite(g, err, 'radius', [spec%radius])
    call require_finite(g, err, 'size', spec%size)
    call require_finite(g, err, 'minor_radius', [spec%minor_radius])
    call require_finite(g, err, 'thickness', [spec%thickness])
    call require_finite(g, err, 'scale', [spec%scale])
    call require_finite(g, err, 'density', [spec%density])
    call require_finite(g, err, 'mass', [spec%mass])
    call require_finite(g, err, 'position', spec%position)
    call require_finite(g, err, 'orientation', spec%orientation)
    call require_finite(g, err, 'velocity', spec%velocity)
    call require_finite(g, err, 'angular_velocity', spec%angular_velocity)
    call require_finite(g, err, 'spacing', spec%spacing)
    call require_finite(g, err, 'jitter_position', [spec%jitter_position])
    call require_finite(g, err, 'jitter_angle', [spec%jitter_angle])
    call require_finite(g, err, 'jitter_velocity', [spec%jitter_velocity])
    call require_finite(g, err, 'inertia', spec%inertia)
    call require_finite(g, err, 'restitution', [spec%restitution])
    call require_finite(g, err, 'friction', [spec%friction])
    if (err%failed()) return
    call check_inertia(g, spec, err)
    if (err%failed()) return

    if (len_trim(spec%name) == 0) then
      call fail(g, err, 'name', 'name must not be blank')
      return
    end if

    ! Shape and the variables that belong to it; a variable of another shape is an error
    ! (a box given a radius is a mistake, not a remark).
    if (.not. given(g, 'shape')) then
      call fail(g, err, '', 'shape is required (one of '//known_shapes//')')
      return
    end if
    if (name_index(shape_names, trim(spec%shape)) == 0) then
      call fail(g, err, 'shape', 'unknown shape '''//trim(spec%shape)//''''// &
                suggestion(trim(spec%shape), shape_names, '')//' (known: '//known_shapes//')')
      return
    end if
    shape = trim(spec%shape)
    call reject_unless(g, err, 'radius', shape == 'sphere' .or. shape == 'cylinder' .or. shape == 'torus', shape)
    call reject_unless(g, err, 'segments', shape == 'cylinder' .or. shape == 'torus', shape)
    call reject_unless(g, err, 'mesh_file', shape == 'mesh', shape)
    call reject_unless(g, err, 'scale', shape == 'mesh', shape)
    call reject_unless(g, err, 'size', shape == 'box' .or. shape == 'cylinder' .or. shape == 'tetrahedron' .or. &
                       shape == 'l_prism', shape)
    call reject_unless(g, err, 'minor_radius', shape == 'torus', shape)
    call reject_unless(g, err, 'tube_segments', shape == 'torus', shape)
    call reject_unless(g, err, 'thickness', shape == 'l_prism', shape)
    if (err%failed()) return
    select case (shape)
    case ('sphere')
      call require_positive(g, err, 'radius', spec%radius, 'm', 'a sphere needs radius [m]')
    case ('box')
      call require_sizes(g, err, spec%size, 'a box needs all three edge lengths: size = x, y, z [m]')
    case ('cylinder')
      ! A cylinder's axis is its z axis: radius and length size(3) (size(1:2) are the box's).
      call require_positive(g, err, 'radius', spec%radius, 'm', 'a cylinder needs radius [m]')
      if (err%failed()) return
      if (given_element(g, 'size', 1) .or. given_element(g, 'size', 2)) then
        call fail_at(g, err, first_element_line(g, 'size', [1, 2]), 'a cylinder takes its length as '// &
                     'size(3) = L [m]; size(1) and size(2) do not apply (give radius)')
      else if (.not. given_element(g, 'size', 3)) then
        call fail(g, err, '', 'a cylinder needs its length: size(3) = L [m]')
      else if (spec%size(3) <= 0.0_dp) then
        call fail(g, err, 'size', 'size(3) (the cylinder''s length) must be > 0 m, got '//real_text(spec%size(3)))
      else if (spec%segments < 3) then
        call fail(g, err, 'segments', 'segments must be >= 3, got '//str(spec%segments))
      end if
    case ('tetrahedron')
      ! Regular: one length says it all, so size(2:3) given would be a mistake, not a remark.
      if (given_element(g, 'size', 2) .or. given_element(g, 'size', 3)) then
        call fail_at(g, err, first_element_line(g, 'size', [2, 3]), 'a tetrahedron takes its edge length as '// &
                     'size(1) = a [m]; size(2) and size(3) do not apply (it is regular)')
      else if (.not. given_element(g, 'size', 1)) then
        call fail(g, err, '', 'a tetrahedron needs its edge length: size(1) = a [m]')
      else if (spec%size(1) <= 0.0_dp) then
        call fail(g, err, 'size', 'size(1) (the tetrahedron''s edge length) must be > 0 m, got '// &
                  real_text(spec%size(1)))
      end if
    case ('torus')
      call require_positive(g, err, 'radius', spec%radius, 'm', &
                            'a torus needs radius [m], the radius of the circle through its tube''s centre')
      call require_positive(g, err, 'minor_radius', spec%minor_radius, 'm', &
                            'a torus needs minor_radius [m], the radius of its tube')
      if (err%failed()) return
      if (spec%minor_radius >= spec%radius) then
        ! r >= R: the tube reaches the axis and the surface would cross itself there.
        call fail(g, err, 'minor_radius', 'minor_radius = '//real_text(spec%minor_radius)// &
                  ' m must be < radius = '//real_text(spec%radius)//' m (the tube would reach the axis)')
      else if (spec%segments < 3) then
        call fail(g, err, 'segments', 'segments must be >= 3, got '//str(spec%segments))
      else if (spec%tube_segments < 3) then
        call fail(g, err, 'tube_segments', 'tube_segments must be >= 3, got '//str(spec%tube_segments))
      else if (2*int(spec%segments, i8)*int(spec%tube_segments, i8) > int(huge(0), i8)) then
        ! The mesh has 2 segments tube_segments faces, counted in default integers.
        call fail(g, err, 'tube_segments', 'segments x tube_segments = '//str(spec%segments)//' x '// &
                  str(spec%tube_segments)//' makes more than '//str(huge(0))//' faces')
      end if
    case ('l_prism')
      call require_sizes(g, err, spec%size, 'an l_prism needs all three lengths: size = x, y, z [m], '// &
                         'the outer edges of the L and its extrusion along z')
      call require_positive(g, err, 'thickness', spec%thickness, 'm', &
                            'an l_prism needs thickness [m], the width of its arms')
      if (err%failed()) return
      if (spec%thickness >= min(spec%size(1), spec%size(2))) then
        call fail(g, err, 'thickness', 'thickness = '//real_text(spec%thickness)// &
                  ' m must be < min(size(1), size(2)) = '//real_text(min(spec%size(1), spec%size(2)))// &
                  ' m (arms that wide fill the rectangle: use a box)')
      end if
    case ('mesh')
      if (.not. given(g, 'mesh_file') .or. len_trim(spec%mesh_file) == 0) then
        call fail(g, err, 'mesh_file', 'a mesh needs mesh_file = ''file''')
        return
      end if
      if (spec%scale <= 0.0_dp) then
        call fail(g, err, 'scale', 'scale must be > 0, got '//real_text(spec%scale))
        return
      end if
      resolved = resolve_path(folder, spec%mesh_file)
      inquire (file=resolved, exist=exists)
      if (.not. exists) then
        call fail(g, err, 'mesh_file', 'mesh_file '''//trim(spec%mesh_file)//''' not found (looked for '// &
                  resolved//')')
      else if (len(resolved) > len(spec%mesh_file)) then
        call fail(g, err, 'mesh_file', 'mesh_file resolved is longer than '//str(len(spec%mesh_file))//' characters')
      else
        spec%mesh_file = resolved
      end if
    end select
    if (err%failed()) return

    ! Mass: exactly one of density and mass (a fixed body needs neither: its mass is infinite).
    if (given(g, 'density') .and. given(g, 'mass')) then
      call fail_at(g, err, max(var_line(g, 'density'), var_line(g, 'mass')), &
                   'give density or mass, not both (density on line '//str(var_line(g, 'density'))// &
                   ', mass on line '//str(var_line(g, 'mass'))//')')
      return
    end if
    if (given(g, 'density')) then
      call require_positive(g, err, 'density', spec%density, 'kg/m^3', '')
    else if (given(g, 'mass')) then
      call require_positive(g, err, 'mass', spec%mass, 'kg', '')
    else if (.not. spec%fixed) then
      call fail(g, err, '', 'give density [kg/m^3] or mass [kg] (only a fixed body needs neither)')
    end if
    if (err%failed()) return

    ! Material: -1 (DECK_AUTO) takes the &contact value when the run is set up.
    if (spec%restitution /= DECK_AUTO .and. (spec%restitution < 0.0_dp .or. spec%restitution > 1.0_dp)) then
      call fail(g, err, 'restitution', 'restitution must be in [0, 1], or -1 for the &contact value, got '// &
                real_text(spec%restitution))
    else if (spec%friction /= DECK_AUTO .and. spec%friction < 0.0_dp) then
      call fail(g, err, 'friction', 'friction must be >= 0, or -1 for the &contact value, got '// &
                real_text(spec%friction))
    end if
    if (err%failed()) return

    ! Orientation: unit within the tolerance, then renormalised. A norm already within a few
    ! ulps of 1 is left alone, so that reading an effective deck back changes no bit.
    norm = norm2(spec%orientation)
    if (abs(norm - 1.0_dp) > unit_quaternion_tolerance) then
      call fail(g, err, 'orientation', 'orientation must be a unit quaternion (w, x, y, z): its norm is '// &
                real_text(norm)//', more than '//real_text(unit_quaternion_tolerance)//' from 1')
      return
    end if
    if (abs(norm - 1.0_dp) > 4.0_dp*epsilon(1.0_dp)) spec%orientation = spec%orientation/norm

    if (spec%fixed) then
      if (any(spec%velocity /= 0.0_dp)) then
        call fail(g, err, 'velocity', 'a fixed body never moves: velocity must be 0')
      else if (any(spec%angular_velocity /= 0.0_dp)) then
        call fail(g, err, 'angular_velocity', 'a fixed body never moves: angular_velocity must be 0')
      else if (spec%jitter_velocity /= 0.0_dp) then
        call fail(g, err, 'jitter_velocity', 'a fixed body never moves: jitter_velocity must be 0')
      end if
      if (err%failed()) return
    end if

    ! Lattice of copies.
    do axis = 1, 3
      if (spec%copies(axis) < 1) then
        call fail(g, err, 'copies', 'copies('//str(axis)//') must be >= 1, got '//str(spec%copies(axis)))
      else if (spec%spacing(axis) < 0.0_dp) then
        call fail(g, err, 'spacing', 'spacing('//str(axis)//') must be >= 0 m, got '//real_text(spec%spacing(axis)))
      else if (spec%copies(axis) > 1 .and. spec%spacing(axis) <= 0.0_dp) then
        call fail(g, err, 'copies', str(spec%copies(axis))//' copies along '//axis_name(axis)// &
                  ' need spacing('//str(axis)//') > 0 m')
      end if
      if (err%failed()) return
    end do
    if (product(int(spec%copies, i8)) > int(huge(0), i8)) then
      call fail(g, err, 'copies', 'copies = '//str(spec%copies(1))//', '//str(spec%copies(2))//', '// &
                str(spec%copies(3))//' makes more than '//str(huge(0))//' bodies')
      return
    end if

    ! Jitter.
    if (spec%jitter_position < 0.0_dp) then
      call fail(g, err, 'jitter_position', 'jitter_position must be >= 0 m, got '//real_text(spec%jitter_position))
    else if (spec%jitter_angle < 0.0_dp .or. spec%jitter_angle > pi) then
      call fail(g, err, 'jitter_angle', 'jitter_angle must be in [0, pi] rad, got '//real_text(spec%jitter_angle))
    else if (spec%jitter_velocity < 0.0_dp) then
      call fail(g, err, 'jitter_velocity', 'jitter_velocity must be >= 0 m/s, got '//real_text(spec%jitter_velocity))
    else if (spec%seed < 0) then
      call fail(g, err, 'seed', 'seed must be >= 0 (0: no jitter), got '//str(spec%seed))
    else if (spec%seed == 0 .and. (spec%jitter_position > 0.0_dp .or. spec%jitter_angle > 0.0_dp .or. &
                                   spec%jitter_velocity > 0.0_dp)) then
      call fail(g, err, 'seed', 'jitter needs a stated seed >= 1 (seed = 0 means no jitter)')
    end if
  end subroutine check_body

  !> Error if the variable is given although the shape does not use it.
  subroutine reject_unless(g, err, name, applies, shape)
    type(group_input_t), intent(in) :: g
    type(error_t), intent(inout) :: err
    character(len=*), intent(in) :: name, shape
    logical, intent(in) :: applies
    if (err%failed() .or. applies) return
    if (given(g, name)) call fail(g, err, name, name//' does not apply to shape '''//trim(shape)//''' ('// &
                                  shape_takes(shape)//')')
  end subroutine reject_unless

  !> What a shape is given, for messages.
  pure function shape_takes(shape) result(text)
    character(len=*), intent(in) :: shape
    character(len=:), allocatable :: text
    select case (trim(shape))
    case ('sphere')
      text = 'a sphere takes radius'
    case ('box')
      text = 'a box takes size = x, y, z'
    case ('cylinder')
      text = 'a cylinder takes radius, size(3) and segments'
    case ('tetrahedron')
      text = 'a tetrahedron takes size(1), its edge length'
    case ('torus')
      text = 'a torus takes radius, minor_radius, segments and tube_segments'
    case ('l_prism')
      text = 'an l_prism takes size = x, y, z and thickness'
    case ('mesh')
      text = 'a mesh takes mesh_file and scale'
    case default
      text = 'known shapes: '//known_shapes
    end select
  end function shape_takes

  !> All three elements of size given and > 0 (box, l_prism); missing says what is needed.
  subroutine require_sizes(g, err, size, missing)
    type(group_input_t), intent(in) :: g
    type(error_t), intent(inout) :: err
    real(dp), intent(in) :: size(3)
    character(len=*), intent(in) :: missing
    integer :: axis
    do axis = 1, 3
      if (err%failed()) return
      if (.not. given_element(g, 'size', axis)) then
        call fail(g, err, 'size', missing//' (size('//str(axis)//') is missing)')
      else if (size(axis) <= 0.0_dp) then
        call fail(g, err, 'size', 'size('//str(axis)//') must be > 0 m, got '//real_text(size(axis)))
      end if
    end do
  end subroutine require_sizes

  subroutine require_positive(g, err, name, value, unit, missing)
    type(group_input_t), intent(in) :: g
    type(error_t), intent(inout) :: err
    character(len=*), intent(in) :: name, unit, missing
    real(dp), intent(in) :: value
    if (err%failed()) return
    if (.not. given(g, name)) then
      call fail(g, err, '', missing)
    else if (value <= 0.0_dp) then
      call fail(g, err, name, name//' must be > 0 '//unit//', got '//real_text(value))
    end if
  end subroutine require_positive

  !> The group in the effective deck: every variable, defaults filled in, auto values as -1;
  !> variables the shape does not use (a box's radius, the mass of a body given by
  !> density) as comments. index: the group's place among the deck's &body groups.
  subroutine write_body_group(spec, index, out)
    type(body_spec_t), intent(in) :: spec
    integer, intent(in) :: index
    type(deck_sink_t), intent(inout) :: out
    character(len=:), allocatable :: shape, note
    associate (b => spec)
      shape = trim(b%shape)
      call out%put('&body ! #'//str(index))
      call put_text(out, 'name', b%name)
      call put_text(out, 'shape', b%shape)
      select case (shape)
      case ('sphere', 'cylinder')
        call put_real(out, 'radius', [b%radius], '[m]')
      case ('torus')
        call put_real(out, 'radius', [b%radius], '[m] major radius, of the tube''s centre circle')
      case default
        call put_note(out, 'radius: not used by shape '''//shape//'''')
      end select
      select case (shape)
      case ('box')
        call put_real(out, 'size', b%size, '[m]')
      case ('l_prism')
        call put_real(out, 'size', b%size, '[m] outer x, y, extrusion z')
      case ('cylinder')
        call put_real(out, 'size(3)', [b%size(3)], '[m] length')
      case ('tetrahedron')
        call put_real(out, 'size(1)', [b%size(1)], '[m] edge length')
      case default
        call put_note(out, 'size: not used by shape '''//shape//'''')
      end select
      if (shape == 'cylinder' .or. shape == 'torus') then
        call put_integer(out, 'segments', [b%segments], '')
      else
        call put_note(out, 'segments: not used by shape '''//shape//'''')
      end if
      if (shape == 'torus') then
        call put_real(out, 'minor_radius', [b%minor_radius], '[m] tube radius')
        call put_integer(out, 'tube_segments', [b%tube_segments], '')
      else
        call put_note(out, 'minor_radius, tube_segments: not used by shape '''//shape//'''')
      end if
      if (shape == 'l_prism') then
        call put_real(out, 'thickness', [b%thickness], '[m] arm width')
      else
        call put_note(out, 'thickness: not used by shape '''//shape//'''')
      end if
      if (shape == 'mesh') then
        call put_text(out, 'mesh_file', b%mesh_file)
        call put_real(out, 'scale', [b%scale], '')
      else
        call put_note(out, 'mesh_file, scale: not used by shape '''//shape//'''')
      end if
      if (b%density > 0.0_dp) then
        call put_real(out, 'density', [b%density], '[kg/m^3]')
        call put_note(out, 'mass: from density')
      else if (b%mass > 0.0_dp) then
        call put_note(out, 'density: from mass')
        call put_real(out, 'mass', [b%mass], '[kg]')
      else
        call put_note(out, 'density, mass: not used (fixed body)')
      end if
      call put_real(out, 'position', b%position, '[m]')
      call put_real(out, 'orientation', b%orientation, 'unit quaternion w, x, y, z')
      call put_real(out, 'velocity', b%velocity, '[m/s]')
      call put_real(out, 'angular_velocity', b%angular_velocity, '[rad/s] world frame')
      call put_logical(out, 'fixed', b%fixed)
      call put_integer(out, 'copies', b%copies, '')
      call put_real(out, 'spacing', b%spacing, '[m]')
      call put_integer(out, 'seed', [b%seed], '0: no jitter')
      call put_real(out, 'jitter_position', [b%jitter_position], '[m]')
      call put_real(out, 'jitter_angle', [b%jitter_angle], '[rad]')
      call put_real(out, 'jitter_velocity', [b%jitter_velocity], '[m/s]')
      if (all(b%inertia == DECK_AUTO)) then
        call put_real(out, 'inertia', b%inertia, '[kg m^2] -1: auto, from the geometry')
      else
        call put_real(out, 'inertia', b%inertia, '[kg m^2] about the shape''s own axes')
      end if
      note = ''
      if (b%restitution == DECK_AUTO) note = '-1: the &contact value'
      call put_real(out, 'restitution', [b%restitution], note)
      note = ''
      if (b%friction == DECK_AUTO) note = '-1: the &contact value'
      call put_real(out, 'friction', [b%friction], note)
      call out%put('/')
    end associate
  end subroutine write_body_group

end module body_group
