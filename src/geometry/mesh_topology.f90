!> Edge topology of a triangle mesh and the checks that make it a solid's surface: every
!> edge shared by exactly two faces (closed, manifold), the two traversing it in opposite
!> directions (consistently oriented), and a non-zero enclosed volume, with normals turned
!> outward. Collision detection and mass properties rely on all of this, so a mesh that
!> fails is refused with a message that lets the user find the defect (file, edge, nodes,
!> coordinates, how many such edges), never silently repaired.
module mesh_topology
  use kinds, only: dp
  use mesh, only: mesh_t
  use error_status, only: error_t, ERR_MESH
  use string_utils, only: str
  implicit none
  private
  public :: build_mesh_topology, signed_volume, vertex_fan_count, component_count, is_convex

  !> A closed surface whose |volume| is below this times (bounding-box diagonal)^3 encloses
  !> nothing (e.g. a doubly covered sheet): no mass properties can come from it.
  real(dp), parameter :: zero_volume_tolerance = 1.0e-12_dp

contains

  !> Builds m%edges, m%edge_faces, m%face_edges and m%n_edges, checks the surface, drops
  !> nodes no face uses (renumbering, order kept) and flips every face if the enclosed
  !> signed volume is negative, so that normals point outward.
  !> Edge e joins nodes edges(1,e) < edges(2,e); edge_faces(1,e) is the face that runs
  !> from edges(1,e) to edges(2,e), edge_faces(2,e) the one that runs back.
  !> Cost: O(n_nodes + n_faces) (two counting-sort passes over the half-edges).
  !> Node numbers in messages are 1-based positions in m%nodes as given (for meshes read by
  !> mesh_io: the file's vertex order). A vertex where two fans of faces touch (a pinched
  !> vertex, every edge still shared by two faces) is accepted: volume, normals and closest
  !> points stay well defined; vertex_fan_count tells such meshes apart.
  !> Disconnected components are allowed; each is checked edge by edge, so each must be
  !> closed and consistently oriented. The flip decision uses the total signed volume, so
  !> an inward-facing inner shell (a cavity inside an outer shell) is kept as it is.
  !> On error no topology arrays are set (unused nodes may already have been dropped) and
  !> err names m%source and the first offending edge with its node indices and coordinates.
  subroutine build_mesh_topology(m, err)
    type(mesh_t), intent(inout) :: m
    type(error_t), intent(inout) :: err
    character(len=:), allocatable :: src
    integer, allocatable :: lo(:), hi(:), order(:), first_at(:), tmp(:)
    integer, allocatable :: edges(:, :), edge_faces(:, :), face_edges(:, :), new_index(:)
    integer :: n_half, h, i, j, k, f, a, b, n_edges, n_nodes, n_faces, group
    integer :: n_bad_index, bad_face, bad_value, n_repeated, repeated_face
    integer :: n_boundary, n_nonmanifold, n_misoriented, n_used
    integer :: boundary_edge(2), nonmanifold_edge(2), nonmanifold_count, misoriented_edge(2), misoriented_faces(2)
    integer :: h1, h2
    logical :: forward1, forward2
    logical, allocatable :: used(:)
    character(len=:), allocatable :: message
    real(dp) :: volume, lower(3), upper(3), diag

    src = 'mesh'
    if (allocated(m%source)) src = "mesh '"//m%source//"'"
    n_nodes = m%n_nodes
    n_faces = m%n_faces
    if (n_faces <= 0 .or. n_nodes <= 0 .or. .not. allocated(m%faces) .or. .not. allocated(m%nodes)) then
      call err%set(ERR_MESH, src//' has no faces (a solid needs a closed triangle surface)')
      return
    end if

    ! Faces referring to missing nodes, and faces that use one node twice: counted over the
    ! whole mesh so the message says how widespread the defect is.
    n_bad_index = 0; bad_face = 0; bad_value = 0
    n_repeated = 0; repeated_face = 0
    do f = 1, n_faces
      if (any(m%faces(:, f) < 1 .or. m%faces(:, f) > n_nodes)) then
        n_bad_index = n_bad_index + 1
        if (bad_face == 0) then
          bad_face = f
          do k = 1, 3
            if (m%faces(k, f) < 1 .or. m%faces(k, f) > n_nodes) then
              bad_value = m%faces(k, f)
              exit
            end if
          end do
        end if
      else if (m%faces(1, f) == m%faces(2, f) .or. m%faces(2, f) == m%faces(3, f) &
               .or. m%faces(3, f) == m%faces(1, f)) then
        n_repeated = n_repeated + 1
        if (repeated_face == 0) repeated_face = f
      end if
    end do
    if (n_bad_index > 0) then
      call err%set(ERR_MESH, src//': '//str(n_bad_index)//' face(s) refer to missing nodes (the mesh has ' &
                   //str(n_nodes)//' nodes); first: face '//str(bad_face)//' refers to node '//str(bad_value))
      return
    end if
    if (n_repeated > 0) then
      call err%set(ERR_MESH, src//': '//str(n_repeated)//' degenerate face(s) use one node twice; first: face ' &
                   //str(repeated_face)//' with nodes '//str(m%faces(1, repeated_face))//', ' &
                   //str(m%faces(2, repeated_face))//', '//str(m%faces(3, repeated_face)))
      return
    end if

    ! Half-edge h = 3(f-1)+k runs from faces(k,f) to faces(mod(k,3)+1,f). Sorting the
    ! half-edges by (smaller node, larger node) puts all uses of one edge side by side:
    ! a stable counting sort by the larger node, then by the smaller one.
    n_half = 3*n_faces
    allocate (lo(n_half), hi(n_half), order(n_half), tmp(n_half), first_at(n_nodes + 1))
    do f = 1, n_faces
      do k = 1, 3
        a = m%faces(k, f)
        b = m%faces(mod(k, 3) + 1, f)
        h = 3*(f - 1) + k
        lo(h) = min(a, b)
        hi(h) = max(a, b)
      end do
    end do
    call counting_sort([(h, h=1, n_half)], hi, n_nodes, first_at, tmp)
    call counting_sort(tmp, lo, n_nodes, first_at, order)
    deallocate (tmp, first_at)

    ! Walk the groups of equal edges: one use is a boundary edge, more than two a
    ! non-manifold edge, two uses in the same direction an orientation flip.
    allocate (edges(2, n_half), edge_faces(2, n_half), face_edges(3, n_faces))
    n_edges = 0
    n_boundary = 0; n_nonmanifold = 0; n_misoriented = 0
    boundary_edge = 0; nonmanifold_edge = 0; nonmanifold_count = 0; misoriented_edge = 0; misoriented_faces = 0
    i = 1
    do while (i <= n_half)
      h1 = order(i)
      j = i
      do while (j < n_half)
        if (lo(order(j + 1)) /= lo(h1) .or. hi(order(j + 1)) /= hi(h1)) exit
        j = j + 1
      end do
      group = j - i + 1
      n_edges = n_edges + 1
      edges(:, n_edges) = [lo(h1), hi(h1)]
      edge_faces(:, n_edges) = 0
      do k = i, j
        h = order(k)
        face_edges(mod(h - 1, 3) + 1, (h - 1)/3 + 1) = n_edges
      end do
      select case (group)
      case (1)
        n_boundary = n_boundary + 1
        if (n_boundary == 1) boundary_edge = edges(:, n_edges)
      case (2)
        h2 = order(j)
        forward1 = is_forward(h1)
        forward2 = is_forward(h2)
        if (forward1 .eqv. forward2) then
          n_misoriented = n_misoriented + 1
          if (n_misoriented == 1) then
            misoriented_edge = edges(:, n_edges)
            misoriented_faces = [(h1 - 1)/3 + 1, (h2 - 1)/3 + 1]
          end if
        else if (forward1) then
          edge_faces(:, n_edges) = [(h1 - 1)/3 + 1, (h2 - 1)/3 + 1]
        else
          edge_faces(:, n_edges) = [(h2 - 1)/3 + 1, (h1 - 1)/3 + 1]
        end if
      case default
        n_nonmanifold = n_nonmanifold + 1
        if (n_nonmanifold == 1) then
          nonmanifold_edge = edges(:, n_edges)
          nonmanifold_count = group
        end if
      end select
      i = j + 1
    end do

    if (n_boundary + n_nonmanifold + n_misoriented > 0) then
      message = ''
      if (n_boundary > 0) then
        message = message//'; open surface: '//str(n_boundary)//' boundary edge(s) used by one face only, first: ' &
                  //edge_text(m, boundary_edge)
      end if
      if (n_nonmanifold > 0) then
        message = message//'; non-manifold: '//str(n_nonmanifold)//' edge(s) used by more than two faces, first: ' &
                  //edge_text(m, nonmanifold_edge)//' used by '//str(nonmanifold_count)//' faces'
      end if
      if (n_misoriented > 0) then
        message = message//'; inconsistent orientation: '//str(n_misoriented) &
                  //' edge(s) traversed in the same direction by both their faces, first: ' &
                  //edge_text(m, misoriented_edge)//' in faces '//str(misoriented_faces(1))//' and ' &
                  //str(misoriented_faces(2))
      end if
      call err%set(ERR_MESH, src//' is not a closed, manifold, consistently oriented surface'//message)
      return
    end if

    ! Drop unused nodes (harmless, e.g. vertices of removed degenerate faces), keeping order.
    allocate (used(n_nodes))
    used = .false.
    do f = 1, n_faces
      used(m%faces(:, f)) = .true.
    end do
    n_used = count(used)
    if (n_used < n_nodes) then
      allocate (new_index(n_nodes))
      new_index = 0
      n_used = 0
      do i = 1, n_nodes
        if (used(i)) then
          n_used = n_used + 1
          new_index(i) = n_used
          m%nodes(:, n_used) = m%nodes(:, i)
        end if
      end do
      m%nodes = m%nodes(:, 1:n_used)
      m%n_nodes = n_used
      do f = 1, n_faces
        m%faces(:, f) = new_index(m%faces(:, f))
      end do
      do i = 1, n_edges
        edges(:, i) = new_index(edges(:, i))   ! order kept, so edges(1,i) < edges(2,i) still
      end do
    end if

    ! Orientation: closed and consistent, so the signed volume is well defined.
    volume = signed_volume(m)
    call m%bounds(lower, upper)
    diag = norm2(upper - lower)
    if (abs(volume) < zero_volume_tolerance*diag**3 .or. abs(volume) == 0.0_dp) then
      call err%set(ERR_MESH, src//' encloses no volume (signed volume '//real_text(volume) &
                   //' against a bounding-box diagonal of '//real_text(diag) &
                   //'): the surface is self-inconsistent, e.g. a doubly covered sheet')
      return
    end if
    if (volume < 0.0_dp) then
      ! Swapping nodes 2 and 3 reverses every face: edge k=1 (nodes 1-2) becomes the old
      ! edge k=3 (nodes 3-1 reversed), k=2 stays, and each edge changes hands.
      do f = 1, n_faces
        a = m%faces(2, f)
        m%faces(2, f) = m%faces(3, f)
        m%faces(3, f) = a
        a = face_edges(1, f)
        face_edges(1, f) = face_edges(3, f)
        face_edges(3, f) = a
      end do
      do i = 1, n_edges
        a = edge_faces(1, i)
        edge_faces(1, i) = edge_faces(2, i)
        edge_faces(2, i) = a
      end do
    end if

    m%n_edges = n_edges
    m%edges = edges(:, 1:n_edges)
    m%edge_faces = edge_faces(:, 1:n_edges)
    call move_alloc(face_edges, m%face_edges)

  contains

    !> Half-edge h runs from its smaller node to its larger one.
    pure logical function is_forward(h)
      integer, intent(in) :: h
      is_forward = m%faces(mod(h - 1, 3) + 1, (h - 1)/3 + 1) == lo(h)
    end function is_forward

  end subroutine build_mesh_topology

  !> Stable counting sort of the items listed in `items` by key(item) in 1..n_keys.
  pure subroutine counting_sort(items, key, n_keys, first_at, sorted)
    integer, intent(in) :: items(:), key(:), n_keys
    integer, intent(out) :: first_at(n_keys + 1), sorted(:)
    integer :: i, c, total
    first_at = 0
    do i = 1, size(items)
      first_at(key(items(i))) = first_at(key(items(i))) + 1
    end do
    total = 1
    do i = 1, n_keys + 1
      c = first_at(i)
      first_at(i) = total
      total = total + c
    end do
    do i = 1, size(items)
      sorted(first_at(key(items(i)))) = items(i)
      first_at(key(items(i))) = first_at(key(items(i))) + 1
    end do
  end subroutine counting_sort

  !> Enclosed signed volume [m^3]: sum over faces of det(p1,p2,p3)/6, positive when the
  !> normals point outward. Taken about the bounding-box centre, which does not change the
  !> result for a closed surface but keeps the determinants small (less cancellation).
  pure real(dp) function signed_volume(m)
    type(mesh_t), intent(in) :: m
    real(dp) :: origin(3), p1(3), p2(3), p3(3), lower(3), upper(3)
    integer :: f
    signed_volume = 0.0_dp
    if (m%n_nodes <= 0 .or. m%n_faces <= 0) return
    call m%bounds(lower, upper)
    origin = 0.5_dp*(lower + upper)
    do f = 1, m%n_faces
      p1 = m%nodes(:, m%faces(1, f)) - origin
      p2 = m%nodes(:, m%faces(2, f)) - origin
      p3 = m%nodes(:, m%faces(3, f)) - origin
      signed_volume = signed_volume + p1(1)*(p2(2)*p3(3) - p2(3)*p3(2)) &
                      + p1(2)*(p2(3)*p3(1) - p2(1)*p3(3)) + p1(3)*(p2(1)*p3(2) - p2(2)*p3(1))
    end do
    signed_volume = signed_volume/6.0_dp
  end function signed_volume

  !> Number of fans of faces around all nodes together (needs the topology): equal to
  !> n_nodes when every vertex is manifold; each pinched vertex where k fans touch adds
  !> k - 1. With it the genus of a closed surface of c components follows from
  !> n_fans - n_edges + n_faces = 2c - 2g (the pinched vertices counted as split).
  !> The corners around a node form cycles: from corner k of face f, cross the edge that
  !> leaves the node in f to the neighbouring face and take its corner at the same node.
  pure integer function vertex_fan_count(m)
    type(mesh_t), intent(in) :: m
    logical, allocatable :: visited(:)
    integer :: start, c, f, k, v, e, g, kg
    allocate (visited(3*m%n_faces))
    visited = .false.
    vertex_fan_count = 0
    do start = 1, 3*m%n_faces
      if (visited(start)) cycle
      vertex_fan_count = vertex_fan_count + 1
      c = start
      do while (.not. visited(c))
        visited(c) = .true.
        f = (c - 1)/3 + 1
        k = mod(c - 1, 3) + 1
        v = m%faces(k, f)
        e = m%face_edges(k, f)
        g = m%edge_faces(1, e) + m%edge_faces(2, e) - f
        do kg = 1, 3
          if (m%faces(kg, g) == v) exit
        end do
        c = 3*(g - 1) + kg
      end do
    end do
  end function vertex_fan_count

  !> Number of connected pieces of the surface (nodes joined by edges; needs the topology).
  pure integer function component_count(m)
    type(mesh_t), intent(in) :: m
    integer, allocatable :: parent(:)
    integer :: e, a, b, i
    allocate (parent(m%n_nodes))
    parent = [(i, i=1, m%n_nodes)]
    do e = 1, m%n_edges
      a = root(m%edges(1, e))
      b = root(m%edges(2, e))
      if (a /= b) parent(max(a, b)) = min(a, b)
    end do
    component_count = 0
    do i = 1, m%n_nodes
      if (root(i) == i) component_count = component_count + 1
    end do
  contains
    pure integer function root(x)
      integer, intent(in) :: x
      root = x
      do while (parent(root) /= root)
        root = parent(root)
      end do
    end function root
  end function component_count

  !> "nodes 12 (x, y, z) and 34 (x, y, z)" for messages.
  function edge_text(m, edge) result(text)
    type(mesh_t), intent(in) :: m
    integer, intent(in) :: edge(2)
    character(len=:), allocatable :: text
    text = 'edge between nodes '//str(edge(1))//' '//point_text(m%nodes(:, edge(1)))//' and ' &
           //str(edge(2))//' '//point_text(m%nodes(:, edge(2)))
  end function edge_text

  function point_text(p) result(text)
    real(dp), intent(in) :: p(3)
    character(len=:), allocatable :: text
    text = '('//real_text(p(1))//', '//real_text(p(2))//', '//real_text(p(3))//')'
  end function point_text

  function real_text(x) result(text)
    real(dp), intent(in) :: x
    character(len=:), allocatable :: text
    text = str(x, '(1pg0.9)')
  end function real_text

  !> A closed, connected, genus-0 surface that is locally convex at every edge (the far
  !> vertex of each neighbouring face lies on or below the face's plane, to a round-off
  !> tolerance of 1e-10 of the bounding-box diagonal) bounds a convex solid. Needs topology.
  !> Convex pairs get the tighter time-of-contact bound (along the normal).
  pure logical function is_convex(m)
    type(mesh_t), intent(in) :: m
    integer :: e, f1, f2, k, far
    real(dp) :: n(3), lower(3), upper(3), tolerance, p0(3)
    is_convex = .false.
    if (.not. m%has_topology()) return
    if (m%n_nodes - m%n_edges + m%n_faces /= 2) return
    if (component_count(m) /= 1) return
    call m%bounds(lower, upper)
    tolerance = 1.0e-10_dp*norm2(upper - lower)
    do e = 1, m%n_edges
      f1 = m%edge_faces(1, e)
      f2 = m%edge_faces(2, e)
      far = 0
      do k = 1, 3
        if (m%faces(k, f2) /= m%edges(1, e) .and. m%faces(k, f2) /= m%edges(2, e)) far = m%faces(k, f2)
      end do
      n = m%face_normal(f1)
      p0 = m%nodes(:, m%edges(1, e))
      if (dot_product(n, m%nodes(:, far) - p0) > tolerance) return
    end do
    is_convex = .true.
  end function is_convex

end module mesh_topology
