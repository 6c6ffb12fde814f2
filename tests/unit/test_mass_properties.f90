!> Mass properties of built-in meshes against closed forms, convergence of faceted round
!> bodies, principal frames of rotated bodies, and the shape factory.
!>
!> Why 1e-13 relative is reachable for the exact (polyhedral) cases: the integration is an
!> exact polynomial identity per face, so only round-off remains. With the origin at the
!> node mean each face term has the size of the body and costs a few dozen flops (~1e-15
!> relative each); summed over at most 20 faces (box 12, tetrahedron 4, icosahedron 20,
!> L-prism 20) the error stays a few 1e-15. Node coordinates themselves carry ~1e-16
!> relative error (sqrt 2, golden ratio), which moves volume and inertia by ~5 times that.
!> 1e-13 leaves a margin of ~20 over this and still catches any wrong factor or term.
program test_mass_properties
  use kinds, only: dp, i8
  use constants, only: pi, two_pi
  use mesh, only: mesh_t
  use shape, only: shape_t, SHAPE_SPHERE, SHAPE_MESH
  use error_status, only: error_t, ERR_MESH
  use mass_properties, only: polyhedron_mass_properties, inertia_defect
  use linear_algebra, only: symmetric_eigen
  use shape_builders, only: box_mesh, cylinder_mesh, icosahedron_mesh, icosphere_mesh, tetrahedron_mesh, &
                            torus_mesh, l_shape_mesh, random_blob_mesh
  use shape_factory, only: make_sphere_shape, make_mesh_shape
  use quaternion, only: quat_exp, quat_to_matrix, quat_identity
  use string_utils, only: str
  use assertions
  implicit none

  real(dp), parameter :: tol = 1.0e-13_dp

  call test_unit_cube()
  call test_box()
  call test_tetrahedron()
  call test_icosahedron()
  call test_rotated_box()
  call test_far_box()
  call test_mesh_shape_of_rotated_box()
  call test_mesh_shape_of_cube()
  call test_icosphere_convergence()
  call test_cylinder_convergence()
  call test_torus()
  call test_l_shape()
  call test_blob()
  call test_sphere_shape()
  call test_errors()
  call test_inertia_defect()
  call test_finish()

contains

  !> Principal moments a rigid body can have: positive, each at most the sum of the other
  !> two (equality for a flat plate, slack 1e-9 of the sum for round-off); and what fails.
  subroutine test_inertia_defect()
    type(mesh_t) :: m
    type(shape_t) :: s
    type(error_t) :: err
    call check(len(inertia_defect([1.0_dp, 2.0_dp, 3.0_dp])) == 0, 'inertia 1, 2, 3 (a plate) is physical')
    call check(len(inertia_defect([2.0_dp, 2.0_dp, 2.0_dp])) == 0, 'isotropic inertia is physical')
    call check(len(inertia_defect([1.0_dp, 2.0_dp, 3.0_dp*(1.0_dp + 1.0e-12_dp)])) == 0, &
               'a plate with round-off above the bound (1e-12) is accepted')
    call check(index(inertia_defect([1.0_dp, 2.0_dp, 3.001_dp]), 'moment 3 exceeds the sum') > 0, &
               'I3 = 3.001 > I1 + I2 = 3 refused')
    call check(index(inertia_defect([4.0_dp, 1.0_dp, 2.0_dp]), 'moment 1 exceeds the sum') > 0, &
               'I1 = 4 > I2 + I3 = 3 refused, in any position')
    call check(index(inertia_defect([-101.5_dp, -99.6_dp, 45.3_dp]), 'not positive definite') > 0, &
               'the moments of issue 19''s pushed-through cube refused')
    call check(index(inertia_defect([0.0_dp, 1.0_dp, 1.0_dp]), 'not positive definite') > 0, &
               'a zero moment (a needle) refused')
    ! A thin plate made as a mesh: its computed moments sit on the bound I3 = I1 + I2 to
    ! round-off, and pass.
    call box_mesh([1.0_dp, 2.0_dp, 1.0e-6_dp], m)
    call make_mesh_shape(m, 'plate', s, err)
    call check(err%ok() .and. len(inertia_defect(s%unit_inertia)) == 0, 'a 1e-6 thin box plate is physical')
  end subroutine test_inertia_defect

  !> Closed-form box: V = abc, I_xx = V (b^2 + c^2)/12 etc. about the centre (any
  !> mechanics text, e.g. Wikipedia "List of moments of inertia", solid cuboid).
  function box_inertia(size) result(inertia)
    real(dp), intent(in) :: size(3)
    real(dp) :: inertia(3, 3), v
    v = product(size)
    inertia = 0.0_dp
    inertia(1, 1) = v*(size(2)**2 + size(3)**2)/12.0_dp
    inertia(2, 2) = v*(size(1)**2 + size(3)**2)/12.0_dp
    inertia(3, 3) = v*(size(1)**2 + size(2)**2)/12.0_dp
  end function box_inertia

  subroutine check_tensor(actual, expected, rtol, what)
    real(dp), intent(in) :: actual(3, 3), expected(3, 3), rtol
    character(len=*), intent(in) :: what
    ! Entries that are 0 in the closed form are compared absolutely against the tensor's scale.
    call check_close_array(reshape(actual, [9]), reshape(expected, [9]), rtol, what, &
                           atol=rtol*maxval(abs(expected)))
  end subroutine check_tensor

  !> Closed, consistently oriented 2-manifold: every directed edge (a -> b) of the faces
  !> occurs exactly once and its reverse (b -> a) exactly once too; Euler characteristic
  !> V - E + F as expected (2 for a sphere-like body, 0 for a torus).
  subroutine check_closed(m, euler, what)
    type(mesh_t), intent(in) :: m
    integer, intent(in) :: euler
    character(len=*), intent(in) :: what
    integer(i8), allocatable :: keys(:)
    integer :: f, k, i, n, bad
    n = 3*m%n_faces
    allocate (keys(n))
    do f = 1, m%n_faces
      do k = 1, 3
        keys(3*(f - 1) + k) = int(m%faces(k, f), i8)*int(m%n_nodes + 1, i8) + int(m%faces(mod(k, 3) + 1, f), i8)
      end do
    end do
    call sort_keys(keys)
    bad = 0
    do i = 1, n
      if (i > 1) then
        if (keys(i) == keys(i - 1)) bad = bad + 1
      end if
      if (.not. has_key(keys, reverse_key(keys(i), m%n_nodes))) bad = bad + 1
    end do
    call check(bad == 0, what//': closed and consistently oriented ('//str(bad)//' bad directed edges)')
    call check(m%n_nodes - n/2 + m%n_faces == euler, what//': Euler characteristic '// &
               str(m%n_nodes - n/2 + m%n_faces)//' expected '//str(euler))
  end subroutine check_closed

  pure integer(i8) function reverse_key(key, n_nodes)
    integer(i8), intent(in) :: key
    integer, intent(in) :: n_nodes
    reverse_key = mod(key, int(n_nodes + 1, i8))*int(n_nodes + 1, i8) + key/int(n_nodes + 1, i8)
  end function reverse_key

  pure logical function has_key(keys, key)
    integer(i8), intent(in) :: keys(:), key
    integer :: low, high, mid
    low = 1
    high = size(keys)
    has_key = .false.
    do while (low <= high)
      mid = (low + high)/2
      if (keys(mid) == key) then
        has_key = .true.
        return
      else if (keys(mid) < key) then
        low = mid + 1
      else
        high = mid - 1
      end if
    end do
  end function has_key

  !> Heapsort (test helper; sizes up to ~1e5).
  pure subroutine sort_keys(a)
    integer(i8), intent(inout) :: a(:)
    integer :: n, i, last
    integer(i8) :: t
    n = size(a)
    do i = n/2, 1, -1
      call sift(a, i, n)
    end do
    do last = n, 2, -1
      t = a(1); a(1) = a(last); a(last) = t
      call sift(a, 1, last - 1)
    end do
  end subroutine sort_keys

  pure subroutine sift(a, start, finish)
    integer(i8), intent(inout) :: a(:)
    integer, intent(in) :: start, finish
    integer :: root, child
    integer(i8) :: tmp
    root = start
    do while (2*root <= finish)
      child = 2*root
      if (child < finish) then
        if (a(child) < a(child + 1)) child = child + 1
      end if
      if (a(root) >= a(child)) return
      tmp = a(root); a(root) = a(child); a(child) = tmp
      root = child
    end do
  end subroutine sift

  !> For a convex body: every face normal points away from the centroid.
  subroutine check_convex_outward(m, what)
    type(mesh_t), intent(in) :: m
    character(len=*), intent(in) :: what
    real(dp) :: c(3)
    integer :: f, bad
    c = sum(m%nodes, dim=2)/m%n_nodes
    bad = 0
    do f = 1, m%n_faces
      if (dot_product(m%face_normal(f), m%nodes(:, m%faces(1, f)) - c) <= 0.0_dp) bad = bad + 1
    end do
    call check(bad == 0, what//': all faces point outward ('//str(bad)//' inward)')
  end subroutine check_convex_outward

  subroutine mass(m, volume, centroid, inertia, what)
    type(mesh_t), intent(in) :: m
    real(dp), intent(out) :: volume, centroid(3), inertia(3, 3)
    character(len=*), intent(in) :: what
    type(error_t) :: err
    call polyhedron_mass_properties(m, volume, centroid, inertia, err)
    call check(err%ok(), what//': mass properties computed')
    if (err%failed()) write (*, '(a)') err%message
  end subroutine mass

  subroutine test_unit_cube()
    type(mesh_t) :: m
    real(dp) :: v, c(3), inertia(3, 3), expected(3, 3)
    call box_mesh([1.0_dp, 1.0_dp, 1.0_dp], m)
    call check(m%n_nodes == 8 .and. m%n_faces == 12, 'cube: 8 nodes, 12 faces')
    call check_closed(m, 2, 'cube')
    call check_convex_outward(m, 'cube')
    call mass(m, v, c, inertia, 'cube')
    ! Unit cube: V = 1, I = 1/6 on the diagonal (box formula with a = b = c = 1).
    call check_close(v, 1.0_dp, tol, 'cube volume')
    call check_close_array(c, [0.0_dp, 0.0_dp, 0.0_dp], 0.0_dp, 'cube centroid', atol=tol)
    expected = 0.0_dp
    expected(1, 1) = 1.0_dp/6.0_dp; expected(2, 2) = 1.0_dp/6.0_dp; expected(3, 3) = 1.0_dp/6.0_dp
    call check_tensor(inertia, expected, tol, 'cube inertia')
  end subroutine test_unit_cube

  subroutine test_box()
    type(mesh_t) :: m
    real(dp) :: v, c(3), inertia(3, 3)
    call box_mesh([1.0_dp, 2.0_dp, 3.0_dp], m)
    call check_closed(m, 2, 'box 1x2x3')
    call check_convex_outward(m, 'box 1x2x3')
    call mass(m, v, c, inertia, 'box 1x2x3')
    call check_close(v, 6.0_dp, tol, 'box volume = abc')
    call check_close_array(c, [0.0_dp, 0.0_dp, 0.0_dp], 0.0_dp, 'box centroid', atol=3*tol)
    call check_tensor(inertia, box_inertia([1.0_dp, 2.0_dp, 3.0_dp]), tol, 'box inertia (13, 10, 5) V/12')
  end subroutine test_box

  subroutine test_tetrahedron()
    type(mesh_t) :: m
    real(dp) :: v, c(3), inertia(3, 3), expected(3, 3), a, v_exact
    integer :: i
    a = 1.7_dp
    call tetrahedron_mesh(a, m)
    call check_closed(m, 2, 'tetrahedron')
    call check_convex_outward(m, 'tetrahedron')
    call check_close(norm2(m%nodes(:, 1) - m%nodes(:, 2)), a, tol, 'tetrahedron edge length')
    call check_close(norm2(m%nodes(:, 3) - m%nodes(:, 4)), a, tol, 'tetrahedron edge length (opposite edge)')
    call mass(m, v, c, inertia, 'tetrahedron')
    ! Regular tetrahedron of edge a: V = a^3/(6 sqrt 2); I = M a^2/20 about every axis
    ! through the centroid (Wikipedia "List of moments of inertia", solid tetrahedron).
    v_exact = a**3/(6.0_dp*sqrt(2.0_dp))
    call check_close(v, v_exact, tol, 'tetrahedron volume a^3/(6 sqrt 2)')
    call check_close_array(c, [0.0_dp, 0.0_dp, 0.0_dp], 0.0_dp, 'tetrahedron centroid', atol=tol*a)
    expected = 0.0_dp
    do i = 1, 3
      expected(i, i) = v_exact*a**2/20.0_dp
    end do
    call check_tensor(inertia, expected, tol, 'tetrahedron inertia V a^2/20')
  end subroutine test_tetrahedron

  subroutine test_icosahedron()
    type(mesh_t) :: m
    real(dp) :: v, c(3), inertia(3, 3), expected(3, 3), r, a, v_exact
    integer :: i
    r = 0.8_dp
    call icosahedron_mesh(r, m)
    call check(m%n_nodes == 12 .and. m%n_faces == 20, 'icosahedron: 12 nodes, 20 faces')
    call check_closed(m, 2, 'icosahedron')
    call check_convex_outward(m, 'icosahedron')
    ! Circumradius r = a sin(2 pi/5), so a = r/sin(2 pi/5). Regular icosahedron of edge a:
    ! V = 5 (3 + sqrt 5) a^3/12 and I = M a^2 (3 + sqrt 5)/20 = M a^2 phi^2/10 about any
    ! centroidal axis (Wikipedia "Regular icosahedron" and "List of moments of inertia").
    a = r/sin(two_pi/5.0_dp)
    call check_close(norm2(m%nodes(:, 1) - m%nodes(:, 2)), a, tol, 'icosahedron edge length')
    v_exact = 5.0_dp*(3.0_dp + sqrt(5.0_dp))*a**3/12.0_dp
    call mass(m, v, c, inertia, 'icosahedron')
    call check_close(v, v_exact, tol, 'icosahedron volume 5 (3 + sqrt 5) a^3/12')
    call check_close_array(c, [0.0_dp, 0.0_dp, 0.0_dp], 0.0_dp, 'icosahedron centroid', atol=tol*r)
    expected = 0.0_dp
    do i = 1, 3
      expected(i, i) = v_exact*a**2*(3.0_dp + sqrt(5.0_dp))/20.0_dp
    end do
    call check_tensor(inertia, expected, tol, 'icosahedron inertia V a^2 (3 + sqrt 5)/20')
  end subroutine test_icosahedron

  !> A fixed, generic rotation ("random" but reproducible) and shift.
  subroutine rotated_box(m, rotation, shift)
    type(mesh_t), intent(inout) :: m
    real(dp), intent(out) :: rotation(3, 3), shift(3)
    integer :: i
    rotation = quat_to_matrix(quat_exp([0.7312_dp, -1.9423_dp, 0.4187_dp]))
    shift = [3.25_dp, -1.5_dp, 0.875_dp]
    call box_mesh([1.0_dp, 2.0_dp, 3.0_dp], m)
    do i = 1, m%n_nodes
      m%nodes(:, i) = matmul(rotation, m%nodes(:, i)) + shift
    end do
  end subroutine rotated_box

  subroutine test_rotated_box()
    type(mesh_t) :: m
    type(error_t) :: err
    real(dp) :: v, c(3), inertia(3, 3), rotation(3, 3), shift(3), moments(3), axes(3, 3)
    integer :: k
    ! Box axis (column of rotation) expected for ascending moments 2.5 (z), 5 (y), 6.5 (x).
    integer, parameter :: box_axis(3) = [3, 2, 1]
    call rotated_box(m, rotation, shift)
    call mass(m, v, c, inertia, 'rotated box')
    call check_close(v, 6.0_dp, tol, 'rotated box volume')
    ! The centroid moves with the body: shift, to round-off of the coordinates (~4 eps).
    call check_close_array(c, shift, tol, 'rotated box centroid = shift')
    call symmetric_eigen(inertia, moments, axes, err)
    call check(err%ok(), 'rotated box: eigen-decomposition')
    call check_close_array(moments, [2.5_dp, 5.0_dp, 6.5_dp], tol, 'rotated box principal moments')
    ! Moments are 2.5 apart at least (relative gap 0.4): axes are determined to
    ! ~round-off/gap, so 1e-12 componentwise holds with a wide margin.
    do k = 1, 3
      call check_close_array(axes(:, k)*sign(1.0_dp, dot_product(axes(:, k), rotation(:, box_axis(k)))), &
                             rotation(:, box_axis(k)), 0.0_dp, 'rotated box principal axis '//str(k), &
                             atol=1.0e-12_dp)
    end do
  end subroutine test_rotated_box

  !> The rotated box 3e4 m from the origin: the node coordinates themselves carry
  !> round-off of 3e4 x 1.1e-16 = 3.3e-12 m, ~1e-11 of the box size, which bounds what any
  !> method can reach. Integrating about the node mean keeps the inertia at that level
  !> (checked to 1e-10). About the coordinate origin the result would be a difference of
  !> terms ~1e4 to 1e13 times larger: measured with that change, the volume was off by
  !> 2.5e-5 relative and the inertia by a factor ~5000.
  subroutine test_far_box()
    type(mesh_t) :: m
    real(dp) :: v, c(3), inertia(3, 3), rotation(3, 3), shift(3), far(3)
    integer :: i
    call rotated_box(m, rotation, shift)
    far = [1.0e4_dp, -2.0e4_dp, 3.0e4_dp]
    do i = 1, m%n_nodes
      m%nodes(:, i) = m%nodes(:, i) + far
    end do
    call mass(m, v, c, inertia, 'far box')
    call check_close(v, 6.0_dp, 1.0e-10_dp, 'far box volume')
    call check_close_array(c, shift + far, 0.0_dp, 'far box centroid', atol=1.0e-10_dp)
    call check_tensor(inertia, matmul(rotation, matmul(box_inertia([1.0_dp, 2.0_dp, 3.0_dp]), transpose(rotation))), &
                      1.0e-10_dp, 'far box inertia')
  end subroutine test_far_box

  subroutine test_mesh_shape_of_rotated_box()
    type(mesh_t) :: m
    type(shape_t) :: s
    type(error_t) :: err
    real(dp) :: rotation(3, 3), shift(3), r(3, 3), v, c(3), inertia(3, 3), local(3), expected(3, 3)
    integer :: j, k
    integer, parameter :: box_axis(3) = [3, 2, 1]
    call rotated_box(m, rotation, shift)
    call make_mesh_shape(m, 'rotated box', s, err)
    call check(err%ok(), 'make_mesh_shape(rotated box) succeeds')
    call check(s%kind == SHAPE_MESH .and. s%label == 'rotated box', 'mesh shape kind and label')
    call check_close(s%volume, 6.0_dp, tol, 'mesh shape volume')
    call check_close_array(s%unit_inertia, [2.5_dp, 5.0_dp, 6.5_dp], tol, 'mesh shape moments ascending')
    call check_close_array(s%com_offset, shift, tol, 'mesh shape com_offset = shift')
    ! R(q)^T maps the definition frame into the principal frame: box axis box_axis(k) must
    ! land on principal axis k (up to sign); 1e-12 as for the axes above.
    r = quat_to_matrix(s%q_principal)
    do k = 1, 3
      local = matmul(transpose(r), rotation(:, box_axis(k)))
      expected(:, k) = 0.0_dp
      expected(k, k) = sign(1.0_dp, local(k))
      call check_close_array(local, expected(:, k), 0.0_dp, 'R(q)^T box axis '//str(box_axis(k))// &
                             ' = principal axis '//str(k), atol=1.0e-12_dp)
    end do
    ! The stored mesh is the body in its principal frame: centroid 0, diagonal inertia.
    call mass(s%mesh, v, c, inertia, 'principal-frame box')
    call check_close_array(c, [0.0_dp, 0.0_dp, 0.0_dp], 0.0_dp, 'principal-frame centroid', atol=tol*3)
    expected = 0.0_dp
    do j = 1, 3
      expected(j, j) = s%unit_inertia(j)
    end do
    call check_tensor(inertia, expected, tol, 'principal-frame inertia diagonal')
    ! The principal frame is the box's own frame with the axes reordered: half-extents
    ! (1.5, 1, 0.5) and bounding radius = half diagonal sqrt(14)/2.
    call check_close_array(s%aabb_upper, [1.5_dp, 1.0_dp, 0.5_dp], tol, 'principal-frame aabb upper')
    call check_close_array(s%aabb_lower, [-1.5_dp, -1.0_dp, -0.5_dp], tol, 'principal-frame aabb lower')
    call check_close(s%bounding_radius, 0.5_dp*sqrt(14.0_dp), tol, 'bounding radius = half diagonal')
    ! Round trip: principal-frame node -> definition frame gives back the input node.
    call check_close_array(s%com_offset + matmul(r, s%mesh%nodes(:, 5)), m%nodes(:, 5), tol, &
                           'p_definition = com_offset + R(q) p_principal')
  end subroutine test_mesh_shape_of_rotated_box

  subroutine test_mesh_shape_of_cube()
    type(mesh_t) :: m
    type(shape_t) :: s
    type(error_t) :: err
    call box_mesh([2.0_dp, 2.0_dp, 2.0_dp], m)
    call make_mesh_shape(m, 'cube', s, err)
    call check(err%ok(), 'make_mesh_shape(cube) succeeds')
    ! A cube's tensor is diagonal and fully degenerate: its principal frame is its own.
    call check_close_array(s%q_principal, quat_identity, 0.0_dp, 'cube principal frame = own frame')
    call check_close_array(s%mesh%nodes(:, 8), [1.0_dp, 1.0_dp, 1.0_dp], 0.0_dp, 'cube mesh unchanged')
  end subroutine test_mesh_shape_of_cube

  !> Faceted sphere: the inscribed icosphere misses a layer of thickness ~h^2/(8R) under
  !> each face of size h, so volume and inertia errors scale as h^2; halving h (one more
  !> level) divides them by ~4. The ratio tends to 4 with corrections of relative order
  !> h^2 (and from the non-uniform face sizes). Measured (printed below): volume 3.74,
  !> 3.93, 3.98, 3.996; inertia 3.61, 3.90, 3.97, 3.993 for levels 1/2 .. 4/5. Checks:
  !> every ratio in [3.5, 4.1] (first order would give 2, third 8) and, once asymptotic,
  !> levels 3/4 and 4/5 within 0.05 of 4.
  subroutine test_icosphere_convergence()
    type(mesh_t) :: m
    real(dp) :: v, c(3), inertia(3, 3), v_exact, i_exact, err_v(5), err_i(5), expected(3, 3), r
    integer :: level, n_dupes, i, j
    r = 1.3_dp
    v_exact = 4.0_dp/3.0_dp*pi*r**3
    i_exact = 0.4_dp*r**2*v_exact
    do level = 1, 5
      call icosphere_mesh(r, level, m)
      call check(m%n_nodes == 10*4**level + 2 .and. m%n_faces == 20*4**level, &
                 'icosphere level '//str(level)//' node and face counts')
      if (level <= 4) then
        call check_closed(m, 2, 'icosphere level '//str(level))
        call check_convex_outward(m, 'icosphere level '//str(level))
        n_dupes = 0
        do j = 2, m%n_nodes
          do i = 1, j - 1
            if (norm2(m%nodes(:, i) - m%nodes(:, j)) < 1.0e-9_dp*r) n_dupes = n_dupes + 1
          end do
        end do
        call check(n_dupes == 0, 'icosphere level '//str(level)//': no duplicate nodes')
      end if
      call check_close(maxval(norm2(m%nodes, dim=1)), r, 1.0e-15_dp*4, 'icosphere nodes on the sphere (max)')
      call check_close(minval(norm2(m%nodes, dim=1)), r, 1.0e-15_dp*4, 'icosphere nodes on the sphere (min)')
      call mass(m, v, c, inertia, 'icosphere')
      err_v(level) = (v_exact - v)/v_exact
      err_i(level) = (i_exact - inertia(1, 1))/i_exact
      ! Icosahedral symmetry makes the tensor isotropic exactly; round-off over 20 4^level
      ! faces stays below 1e-13 of the diagonal.
      expected = 0.0_dp
      do i = 1, 3
        expected(i, i) = inertia(1, 1)
      end do
      call check_tensor(inertia, expected, 1.0e-13_dp, 'icosphere level '//str(level)//' inertia isotropic')
      call check_close_array(c, [0.0_dp, 0.0_dp, 0.0_dp], 0.0_dp, 'icosphere centroid', atol=1.0e-13_dp*r)
      write (*, '(a,i0,a,es10.3,a,es10.3)') 'icosphere level ', level, ': volume error ', err_v(level), &
        ', inertia error ', err_i(level)
    end do
    call check(all(err_v > 0.0_dp) .and. all(err_i > 0.0_dp), 'inscribed icosphere is smaller than the sphere')
    do level = 1, 4
      write (*, '(a,i0,a,i0,a,f7.4,a,f7.4)') 'icosphere error ratio ', level, '/', level + 1, ': volume ', &
        err_v(level)/err_v(level + 1), ', inertia ', err_i(level)/err_i(level + 1)
      call check(err_v(level)/err_v(level + 1) > 3.5_dp .and. err_v(level)/err_v(level + 1) < 4.1_dp, &
                 'icosphere volume error ratio ~4 (second order), levels '//str(level)//'/'//str(level + 1))
      call check(err_i(level)/err_i(level + 1) > 3.5_dp .and. err_i(level)/err_i(level + 1) < 4.1_dp, &
                 'icosphere inertia error ratio ~4 (second order), levels '//str(level)//'/'//str(level + 1))
      if (level >= 3) then
        call check(abs(err_v(level)/err_v(level + 1) - 4.0_dp) < 0.05_dp, &
                   'icosphere volume error ratio asymptotically 4, levels '//str(level)//'/'//str(level + 1))
        call check(abs(err_i(level)/err_i(level + 1) - 4.0_dp) < 0.05_dp, &
                   'icosphere inertia error ratio asymptotically 4, levels '//str(level)//'/'//str(level + 1))
      end if
    end do
    call check(err_v(5) < 2.0e-3_dp, 'icosphere level 5 volume within 0.2 %')
  end subroutine test_icosphere_convergence

  !> Faceted cylinder: a regular s-gon prism inscribed in the cylinder. With alpha = 2 pi/s
  !> its closed forms (sum of s triangles from the axis) are
  !>   V   = L s r^2 sin(alpha)/2,
  !>   Izz = L J, J = s r^4 sin(alpha) (2 + cos alpha)/12 (polar moment of the polygon;
  !>         triangle (0, a, b): J = A (|a|^2 + |b|^2 + a.b)/6),
  !>   Ixx = Iyy = L J/2 + A L^3/12 (a regular polygon's in-plane moments are isotropic),
  !> which the mesh must match to round-off (1e-13 relative: up to 1024 faces of
  !> well-conditioned terms). Against the smooth cylinder (V = pi r^2 L, Izz = V r^2/2,
  !> Ixx = V (3 r^2 + L^2)/12) the errors are 1 - sin(alpha)/alpha ~ alpha^2/6: second
  !> order, the ratio for doubled s is 4 (1 - 3 alpha^2/80 + ...) in [3.97, 4.0] here.
  subroutine test_cylinder_convergence()
    type(mesh_t) :: m
    real(dp) :: v, c(3), inertia(3, 3), r, length, alpha, area, polar, expected(3, 3), v_smooth, izz_smooth
    real(dp) :: err_v(5), err_i(5)
    integer :: k, segments
    r = 0.6_dp
    length = 2.5_dp
    v_smooth = pi*r**2*length
    izz_smooth = 0.5_dp*v_smooth*r**2
    do k = 1, 5
      segments = 16*2**(k - 1)
      call cylinder_mesh(r, length, segments, m)
      call check(m%n_nodes == 2*segments + 2 .and. m%n_faces == 4*segments, 'cylinder counts')
      call check_closed(m, 2, 'cylinder '//str(segments))
      call check_convex_outward(m, 'cylinder '//str(segments))
      call mass(m, v, c, inertia, 'cylinder')
      alpha = two_pi/segments
      area = 0.5_dp*segments*r**2*sin(alpha)
      polar = segments*r**4*sin(alpha)*(2.0_dp + cos(alpha))/12.0_dp
      call check_close(v, area*length, tol, 'cylinder '//str(segments)//' volume = faceted closed form')
      expected = 0.0_dp
      expected(1, 1) = 0.5_dp*length*polar + area*length**3/12.0_dp
      expected(2, 2) = expected(1, 1)
      expected(3, 3) = length*polar
      call check_tensor(inertia, expected, tol, 'cylinder '//str(segments)//' inertia = faceted closed form')
      call check_close_array(c, [0.0_dp, 0.0_dp, 0.0_dp], 0.0_dp, 'cylinder centroid', atol=tol*length)
      err_v(k) = (v_smooth - v)/v_smooth
      err_i(k) = (izz_smooth - inertia(3, 3))/izz_smooth
    end do
    do k = 1, 4
      write (*, '(a,i0,a,es10.3,a,f7.4,a,f7.4)') 'cylinder ', 16*2**(k - 1), ' segments: volume error ', &
        err_v(k), ', ratio volume ', err_v(k)/err_v(k + 1), ', ratio Izz ', err_i(k)/err_i(k + 1)
      call check(err_v(k)/err_v(k + 1) > 3.95_dp .and. err_v(k)/err_v(k + 1) < 4.01_dp, &
                 'cylinder volume error ratio ~4 (second order)')
      ! Izz error 1 - sinc(alpha) (2 + cos alpha)/3 ~ alpha^2/3: second order as well.
      call check(err_i(k)/err_i(k + 1) > 3.9_dp .and. err_i(k)/err_i(k + 1) < 4.05_dp, &
                 'cylinder Izz error ratio ~4 (second order)')
    end do
  end subroutine test_cylinder_convergence

  !> Faceted torus: every quad is a planar trapezoid, so the mesh is exactly a regular
  !> n_minor-gon (inscribed in the tube circle) swept around z by a regular n_major-gon;
  !> by Pappus for polygonal sweeps V = n_M sin(2 pi/n_M) A_P R with A_P the polygon area,
  !> i.e. V = 2 pi^2 R r^2 sinc(2 pi/n_M) sinc(2 pi/n_m). Faceting error against the
  !> smooth torus: 0 < 1 - sinc(a) sinc(b) <= (a^2 + b^2)/6.
  subroutine test_torus()
    type(mesh_t) :: m
    real(dp) :: v, c(3), inertia(3, 3), big_r, small_r, a, b, v_smooth, v_faceted, bound
    integer, parameter :: n_major = 48, n_minor = 24
    big_r = 2.0_dp
    small_r = 0.5_dp
    call torus_mesh(big_r, small_r, n_major, n_minor, m)
    call check_closed(m, 0, 'torus')
    call mass(m, v, c, inertia, 'torus')
    a = two_pi/n_major
    b = two_pi/n_minor
    v_smooth = 2.0_dp*pi**2*big_r*small_r**2
    v_faceted = v_smooth*(sin(a)/a)*(sin(b)/b)
    bound = (a**2 + b**2)/6.0_dp
    write (*, '(a,es10.3,a,es10.3)') 'torus volume error ', (v_smooth - v)/v_smooth, ' bound ', bound
    call check(v < v_smooth .and. (v_smooth - v)/v_smooth <= bound, 'torus volume within its faceting bound')
    ! 2304 faces: round-off stays near 1e-14; 1e-12 leaves margin.
    call check_close(v, v_faceted, 1.0e-12_dp, 'torus volume = faceted closed form')
    call check_close_array(c, [0.0_dp, 0.0_dp, 0.0_dp], 0.0_dp, 'torus centroid', atol=1.0e-13_dp*big_r)
  end subroutine test_torus

  !> L-prism = box [0,a] x [0,t] x [0,c] united with box [0,t] x [t,b] x [0,c]: volume,
  !> centroid and (parallel-axis theorem) inertia from the two boxes.
  subroutine test_l_shape()
    type(mesh_t) :: m
    real(dp) :: v, c(3), inertia(3, 3), size(3), t, v1, v2, c1(3), c2(3), cg(3), expected(3, 3), d(3)
    real(dp) :: lower(3), upper(3)
    integer :: i
    size = [3.0_dp, 2.0_dp, 0.7_dp]
    t = 0.4_dp
    call l_shape_mesh(size, t, m)
    call check_closed(m, 2, 'L-prism')
    call m%bounds(lower, upper)
    call check_close_array(upper, 0.5_dp*size, tol, 'L-prism centred on its bounding box (upper)')
    call check_close_array(lower, -0.5_dp*size, tol, 'L-prism centred on its bounding box (lower)')
    call mass(m, v, c, inertia, 'L-prism')
    v1 = size(1)*t*size(3)
    v2 = t*(size(2) - t)*size(3)
    ! Box centres relative to the bounding-box centre.
    c1 = [0.5_dp*size(1), 0.5_dp*t, 0.0_dp] - [0.5_dp*size(1), 0.5_dp*size(2), 0.0_dp]
    c2 = [0.5_dp*t, 0.5_dp*(size(2) + t), 0.0_dp] - [0.5_dp*size(1), 0.5_dp*size(2), 0.0_dp]
    ! Closed forms: V = t (a + b - t) c; x = (a^2 + t (b - t))/(2 (a + b - t)) - a/2,
    ! y = (a t + b^2 - t^2)/(2 (a + b - t)) - b/2.
    call check_close(v, t*(size(1) + size(2) - t)*size(3), tol, 'L-prism volume t (a + b - t) c')
    cg = [(size(1)**2 + t*(size(2) - t))/(2.0_dp*(size(1) + size(2) - t)) - 0.5_dp*size(1), &
          (size(1)*t + size(2)**2 - t**2)/(2.0_dp*(size(1) + size(2) - t)) - 0.5_dp*size(2), 0.0_dp]
    call check_close_array(c, cg, tol, 'L-prism centroid (closed form)', atol=tol*maxval(size))
    call check_close_array(cg, (v1*c1 + v2*c2)/(v1 + v2), tol, 'L-prism closed-form centroid = box average', &
                           atol=tol*maxval(size))
    expected = box_inertia([size(1), t, size(3)]) + box_inertia([t, size(2) - t, size(3)])
    do i = 1, 2
      if (i == 1) d = c1 - cg
      if (i == 2) d = c2 - cg
      ! Parallel axis: + V_i (|d|^2 1 - d d^T).
      expected = expected + merge(v1, v2, i == 1)*(dot_product(d, d)*identity() - outer3(d, d))
    end do
    call check_tensor(inertia, expected, tol, 'L-prism inertia (two boxes, parallel axes)')
  end subroutine test_l_shape

  pure function identity() result(e)
    real(dp) :: e(3, 3)
    e = 0.0_dp
    e(1, 1) = 1.0_dp; e(2, 2) = 1.0_dp; e(3, 3) = 1.0_dp
  end function identity

  pure function outer3(a, b) result(o)
    real(dp), intent(in) :: a(3), b(3)
    real(dp) :: o(3, 3)
    integer :: j
    do j = 1, 3
      o(:, j) = a*b(j)
    end do
  end function outer3

  subroutine test_blob()
    type(mesh_t) :: m, m2, m3
    type(shape_t) :: s
    type(error_t) :: err
    real(dp) :: v, c(3), inertia(3, 3), rmin, rmax, n(3), worst, expected(3, 3)
    integer :: f, i, j
    call random_blob_mesh(1.0_dp, 0.3_dp, 3, 12345, m)
    call check_closed(m, 2, 'blob')
    rmin = minval(norm2(m%nodes, dim=1))
    rmax = maxval(norm2(m%nodes, dim=1))
    write (*, '(a,f6.3,a,f6.3)') 'blob radii ', rmin, ' .. ', rmax
    ! |f| <= 1: radii within [0.7, 1.3]; a useful blob uses a good part of that range.
    call check(rmin >= 0.7_dp - 1.0e-15_dp .and. rmax <= 1.3_dp + 1.0e-15_dp .and. rmax - rmin > 0.2_dp, &
               'blob radii within radius (1 +- amplitude) and varied')
    ! Non-convex: some node lies clearly (> 1 % of the radius) outside some face's plane.
    worst = 0.0_dp
    do f = 1, m%n_faces
      n = m%face_normal(f)
      do i = 1, m%n_nodes
        worst = max(worst, dot_product(n, m%nodes(:, i) - m%nodes(:, m%faces(1, f))))
      end do
    end do
    call check(worst > 0.01_dp, 'blob is non-convex (max height above a face plane '//str(worst)//')')
    call random_blob_mesh(1.0_dp, 0.3_dp, 3, 12345, m2)
    call check(all(m2%nodes == m%nodes) .and. all(m2%faces == m%faces), 'blob is deterministic')
    call random_blob_mesh(1.0_dp, 0.3_dp, 3, 54321, m3)
    call check(maxval(abs(m3%nodes - m%nodes)) > 0.01_dp, 'another seed gives another blob')
    call mass(m, v, c, inertia, 'blob')
    call check(v > 0.0_dp, 'blob volume positive')
    call make_mesh_shape(m, 'blob', s, err)
    call check(err%ok(), 'make_mesh_shape(blob) succeeds')
    call mass(s%mesh, v, c, inertia, 'principal-frame blob')
    ! Round-off over 1280 faces; the centroid is compared with the body size (1 m).
    call check_close_array(c, [0.0_dp, 0.0_dp, 0.0_dp], 0.0_dp, 'principal-frame blob centroid', atol=1.0e-13_dp)
    expected = 0.0_dp
    do j = 1, 3
      expected(j, j) = s%unit_inertia(j)
    end do
    call check_tensor(inertia, expected, 1.0e-12_dp, 'principal-frame blob inertia diagonal')
    call check(s%unit_inertia(1) <= s%unit_inertia(2) .and. s%unit_inertia(2) <= s%unit_inertia(3), &
               'blob moments ascending')
    call check_close(s%bounding_radius, maxval(norm2(s%mesh%nodes, dim=1)), 0.0_dp, 'blob bounding radius')
  end subroutine test_blob

  subroutine test_sphere_shape()
    type(shape_t) :: s
    real(dp) :: r, v
    r = 0.25_dp
    call make_sphere_shape(r, s)
    v = 4.0_dp/3.0_dp*pi*r**3
    call check(s%kind == SHAPE_SPHERE, 'sphere shape kind')
    call check(s%label == 'sphere r='//str(r), 'sphere label "'//s%label//'"')
    ! Exact closed forms evaluated the same way: only the last bit may differ.
    call check_close(s%volume, v, 1.0e-15_dp, 'sphere volume 4/3 pi r^3')
    call check_close_array(s%unit_inertia, [1.0_dp, 1.0_dp, 1.0_dp]*0.4_dp*r**2*v, 1.0e-15_dp, &
                           'sphere inertia 2/5 r^2 V')
    call check_close(s%bounding_radius, r, 0.0_dp, 'sphere bounding radius')
    call check_close_array(s%aabb_upper, [r, r, r], 0.0_dp, 'sphere aabb upper')
    call check_close_array(s%aabb_lower, -[r, r, r], 0.0_dp, 'sphere aabb lower')
    call check(s%mesh%n_faces == 0, 'sphere has no mesh')
  end subroutine test_sphere_shape

  subroutine test_errors()
    type(mesh_t) :: m
    type(shape_t) :: s
    type(error_t) :: err
    real(dp) :: v, c(3), inertia(3, 3)
    ! Inward faces: negative volume is refused.
    call box_mesh([1.0_dp, 1.0_dp, 1.0_dp], m)
    m%faces = m%faces([1, 3, 2], :)
    call polyhedron_mass_properties(m, v, c, inertia, err)
    call check_error(err%code, err%message, [character(len=16) :: 'box 1', 'volume', 'inward'], &
                     'inward box refused')
    call check(err%code == ERR_MESH, 'inward box: ERR_MESH')
    ! An invalid builder argument gives an empty mesh that the factory reports.
    call box_mesh([1.0_dp, -2.0_dp, 1.0_dp], m)
    call check(m%n_faces == 0, 'invalid box gives an empty mesh')
    call make_mesh_shape(m, 'bad box', s, err)
    call check_error(err%code, err%message, [character(len=24) :: 'bad box', 'box_mesh: invalid size', &
                                             'no faces'], 'invalid box reported with its reason')
    call cylinder_mesh(1.0_dp, 1.0_dp, 2, m)
    call check(m%n_faces == 0 .and. index(m%source, 'segments') > 0, 'cylinder with 2 segments refused')
    call torus_mesh(1.0_dp, 1.0_dp, 8, 8, m)
    call check(m%n_faces == 0, 'torus with r = R refused')
    call l_shape_mesh([1.0_dp, 1.0_dp, 1.0_dp], 1.0_dp, m)
    call check(m%n_faces == 0, 'L with thickness = size refused')
    call random_blob_mesh(1.0_dp, 1.0_dp, 2, 1, m)
    call check(m%n_faces == 0, 'blob with amplitude 1 refused')
    ! A flat (open, zero-volume) mesh: two triangles back to back.
    call m%init(reshape([0.0_dp, 0.0_dp, 0.0_dp, 1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp, 1.0_dp, 0.0_dp], [3, 3]), &
                reshape([1, 2, 3, 1, 3, 2], [3, 2]), 'flat pair')
    call polyhedron_mass_properties(m, v, c, inertia, err)
    call check_error(err%code, err%message, [character(len=16) :: 'flat pair', 'volume'], 'flat mesh refused')
  end subroutine test_errors

end program test_mass_properties
