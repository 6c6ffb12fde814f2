!> SKD-tree of a triangle mesh: a binary tree of bounding boxes in the body frame. The
!> root bounds all faces; each internal box is split along its longest axis at the median
!> face centroid, so each child holds half of its parent's faces; leaves hold at most
!> LEAF_SIZE faces. Built once per shape and shared (read-only) by every body of that shape.
!> Each box is oriented along the principal axes of its vertices (or axis-aligned when
!> that is smaller): a patch of a curved surface then gets a thin box, which is what makes
!> the distance bounds between boxes tight (axis-aligned boxes of oblique patches are as
!> thick as they are wide, and the pruning suffers accordingly).
!>
!> Layout (flat arrays, no pointers): boxes in depth-first order, so the left child of box
!> k is k + 1 and only the right child index is stored; box(:, k) holds centre, half
!> extents and axes. Faces are stored in leaf order ("slots") with their
!> coordinates copied in (tri(:, v, slot)), so a leaf's triangles are contiguous in memory.
!>
!> Vertices and edges share the face tree instead of having trees of their own: every
!> vertex and every edge is "owned" by exactly one face slot (flags bits), and a query
!> tests a vertex or an edge only where its owner face sits. A feature lies inside its
!> owner face's box, so any feature pair closer than the current best lies in a box pair
!> that the pruned traversal still visits: no pair is missed and none is tested twice,
!> and vertices and edges come out of the same contiguous leaf data as the faces.
module skd_tree
  use kinds, only: dp, i8
  use vector_ops, only: cross
  use mesh, only: mesh_t
  use error_status, only: error_t, ERR_MESH, ERR_INTERNAL
  use string_utils, only: str
  use sorting, only: select_kth
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  implicit none
  private
  public :: skd_tree_t, LEAF_SIZE, owns_vertex, owns_edge, sharp_edge

  integer, parameter :: LEAF_SIZE = 2   !< most faces in a leaf
  !> Two faces sharing an edge are "flat" (the edge is not a crease: a diagonal of a box face)
  !> when their unit normals agree to this cosine; flat edges give no edge-edge contacts.
  real(dp), parameter :: flat_cosine = 1.0_dp - 1.0e-9_dp

  type :: skd_tree_t
    integer :: n_faces = 0          !< faces (= slots)
    integer :: n_boxes = 0          !< tree boxes
    integer :: n_mesh_nodes = 0     !< nodes of the mesh it was built from
    integer :: depth = 0            !< levels (1 for a single leaf)
    real(dp) :: radius = 0.0_dp     !< half diagonal of the root box [m], a length scale
    !> (15, n_boxes) oriented box: centre (1:3) [m], half extents (4:6) [m] along its axes,
    !> the axes as the columns of a rotation (7:15), all in the body frame
    real(dp), allocatable :: box(:, :)
    integer, allocatable :: right(:)          !< (n_boxes) right child, 0 for a leaf (left = k + 1)
    integer, allocatable :: first(:)          !< (n_boxes) first slot of the box's faces
    integer, allocatable :: count(:)          !< (n_boxes) number of faces under the box
    real(dp), allocatable :: tri(:, :, :)     !< (3, 3, n_faces) vertex coordinates per slot [m]
    real(dp), allocatable :: normal(:, :)     !< (3, n_faces) unit outward normal per slot
    integer, allocatable :: face_id(:)        !< (n_faces) mesh face of each slot
    integer, allocatable :: tri_nodes(:, :)   !< (3, n_faces) mesh node indices per slot
    integer, allocatable :: flags(:)          !< (n_faces) ownership bits, see owns_vertex etc.
    real(dp), allocatable :: half_edge(:, :)  !< (3, n_faces) half length of edge k of each slot [m]
  contains
    procedure :: build => tree_build
    procedure :: free => tree_free
  end type skd_tree_t

contains

  !> Slot owns its k-th vertex (k = 1..3).
  elemental logical function owns_vertex(flags, k)
    integer, intent(in) :: flags, k
    owns_vertex = btest(flags, k - 1)
  end function owns_vertex

  !> Slot owns its k-th edge, from vertex k to vertex mod(k, 3) + 1.
  elemental logical function owns_edge(flags, k)
    integer, intent(in) :: flags, k
    owns_edge = btest(flags, k + 2)
  end function owns_edge

  !> The k-th edge is a crease (its two faces are not coplanar, or it is a border edge).
  elemental logical function sharp_edge(flags, k)
    integer, intent(in) :: flags, k
    sharp_edge = btest(flags, k + 5)
  end function sharp_edge

  subroutine tree_free(self)
    class(skd_tree_t), intent(inout) :: self
    if (allocated(self%box)) deallocate (self%box)
    if (allocated(self%right)) deallocate (self%right)
    if (allocated(self%first)) deallocate (self%first)
    if (allocated(self%count)) deallocate (self%count)
    if (allocated(self%tri)) deallocate (self%tri)
    if (allocated(self%normal)) deallocate (self%normal)
    if (allocated(self%face_id)) deallocate (self%face_id)
    if (allocated(self%tri_nodes)) deallocate (self%tri_nodes)
    if (allocated(self%flags)) deallocate (self%flags)
    if (allocated(self%half_edge)) deallocate (self%half_edge)
    self%n_faces = 0
    self%n_boxes = 0
    self%n_mesh_nodes = 0
    self%depth = 0
    self%radius = 0.0_dp
  end subroutine tree_free

  !> Builds the tree of mesh m (body frame). O(n log n). Needs only nodes and faces: the
  !> unique edges are found here by sorting node-pair keys, whether or not m has topology.
  subroutine tree_build(self, m, err)
    class(skd_tree_t), intent(inout) :: self
    type(mesh_t), intent(in) :: m
    type(error_t), intent(inout) :: err
    integer :: nf, i, k, slot, f, max_boxes
    integer, allocatable :: perm(:)
    real(dp), allocatable :: centroid(:, :), key(:)
    character(len=:), allocatable :: name

    call self%free()
    name = 'mesh'
    if (allocated(m%source)) name = "mesh '"//m%source//"'"
    nf = m%n_faces
    if (nf < 1 .or. .not. allocated(m%faces) .or. .not. allocated(m%nodes)) then
      call err%set(ERR_MESH, name//': no faces to build a tree from')
      return
    end if
    do f = 1, nf
      do k = 1, 3
        if (m%faces(k, f) < 1 .or. m%faces(k, f) > m%n_nodes) then
          call err%set(ERR_MESH, name//': face '//str(f)//' refers to node '//str(m%faces(k, f))// &
                       ' outside 1..'//str(m%n_nodes))
          return
        end if
      end do
    end do
    do i = 1, m%n_nodes
      if (.not. all(ieee_is_finite(m%nodes(:, i)))) then
        call err%set(ERR_MESH, name//': node '//str(i)//' has a non-finite coordinate')
        return
      end if
    end do

    self%n_faces = nf
    self%n_mesh_nodes = m%n_nodes
    allocate (perm(nf), centroid(3, nf))
    do f = 1, nf
      perm(f) = f
      centroid(:, f) = (m%nodes(:, m%faces(1, f)) + m%nodes(:, m%faces(2, f)) + m%nodes(:, m%faces(3, f)))/3.0_dp
    end do
    ! The exact number of boxes (the median splits fix it from nf alone): no array twice too
    ! large to trim afterwards (for 10^6 faces 240 MB allocated and 126 MB copied).
    max_boxes = boxes_for(nf)
    allocate (self%box(15, max_boxes), self%right(max_boxes), self%first(max_boxes), self%count(max_boxes))
    allocate (key(nf))
    self%n_boxes = 0
    call build_box(self, m, perm, centroid, key, 1, nf, 1)
    deallocate (key, centroid)
    if (self%n_boxes /= max_boxes) then
      call err%set(ERR_INTERNAL, name//': SKD-tree built '//str(self%n_boxes)//' boxes, expected '//str(max_boxes))
      return
    end if
    self%radius = norm2(self%box(4:6, 1))

    allocate (self%tri(3, 3, nf), self%normal(3, nf), self%face_id(nf), self%tri_nodes(3, nf), self%flags(nf), &
              self%half_edge(3, nf))
    do slot = 1, nf
      f = perm(slot)
      self%face_id(slot) = f
      self%tri_nodes(:, slot) = m%faces(:, f)
      do k = 1, 3
        self%tri(:, k, slot) = m%nodes(:, m%faces(k, f))
      end do
      self%normal(:, slot) = unit_normal(self%tri(:, :, slot))
      do k = 1, 3
        self%half_edge(k, slot) = 0.5_dp*norm2(self%tri(:, mod(k, 3) + 1, slot) - self%tri(:, k, slot))
      end do
    end do
    call assign_owners(self)
  end subroutine tree_build

  !> Boxes of a tree over n faces: build_box splits n > LEAF_SIZE faces into n/2 and the rest.
  pure recursive integer function boxes_for(n) result(boxes)
    integer, intent(in) :: n
    if (n <= LEAF_SIZE) then
      boxes = 1
    else
      boxes = 1 + boxes_for(n/2) + boxes_for(n - n/2)
    end if
  end function boxes_for

  recursive subroutine build_box(self, m, perm, centroid, key, lo, hi, level)
    type(skd_tree_t), intent(inout) :: self
    type(mesh_t), intent(in) :: m
    integer, intent(inout) :: perm(:)
    real(dp), intent(in) :: centroid(:, :)
    real(dp), intent(inout) :: key(:)
    integer, intent(in) :: lo, hi, level
    integer :: k, i, j, c, mid, longest
    real(dp) :: lower(3), upper(3), mean(3), cov(3, 3), axes(3, 3), x(3), v(3), plo(3), phi(3), n_pts
    self%n_boxes = self%n_boxes + 1
    k = self%n_boxes
    self%depth = max(self%depth, level)
    ! Axis-aligned bounds and the principal axes of the node's vertices.
    lower = huge(1.0_dp)
    upper = -huge(1.0_dp)
    mean = 0.0_dp
    do i = lo, hi
      do j = 1, 3
        x = m%nodes(:, m%faces(j, perm(i)))
        lower = min(lower, x)
        upper = max(upper, x)
        mean = mean + x
      end do
    end do
    n_pts = 3.0_dp*(hi - lo + 1)
    mean = mean/n_pts
    ! (Outer products and projections written out: the array intrinsics spread and matmul
    ! made temporaries per vertex, the larger part of the build of a 10^6-face tree.)
    cov = 0.0_dp
    do i = lo, hi
      do j = 1, 3
        x = m%nodes(:, m%faces(j, perm(i))) - mean
        do c = 1, 3
          cov(:, c) = cov(:, c) + x*x(c)
        end do
      end do
    end do
    call jacobi_eigenvectors(cov/n_pts, axes)
    plo = huge(1.0_dp)
    phi = -huge(1.0_dp)
    do i = lo, hi
      do j = 1, 3
        x = m%nodes(:, m%faces(j, perm(i)))
        v = x(1)*axes(1, :) + x(2)*axes(2, :) + x(3)*axes(3, :)
        plo = min(plo, v)
        phi = max(phi, v)
      end do
    end do
    ! Keep the oriented box unless the axis-aligned one is smaller (volume).
    if (product(upper - lower) < product(phi - plo)) then
      axes = reshape([1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp, 1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp, 1.0_dp], [3, 3])
      plo = lower
      phi = upper
    end if
    self%box(1:3, k) = matmul(axes, 0.5_dp*(plo + phi))
    self%box(4:6, k) = 0.5_dp*(phi - plo)
    self%box(7:15, k) = reshape(axes, [9])
    self%first(k) = lo
    self%count(k) = hi - lo + 1
    self%right(k) = 0
    if (hi - lo + 1 <= LEAF_SIZE) return
    ! Longest axis of the box; the median centroid along it splits the faces in halves.
    longest = maxloc(phi - plo, dim=1)
    do i = lo, hi
      key(perm(i)) = dot_product(axes(:, longest), centroid(:, perm(i)))
    end do
    mid = lo + (hi - lo + 1)/2 - 1
    call select_kth(perm, key, lo, hi, mid)
    call build_box(self, m, perm, centroid, key, lo, mid, level + 1)
    self%right(k) = self%n_boxes + 1
    call build_box(self, m, perm, centroid, key, mid + 1, hi, level + 1)
  end subroutine build_box

  !> Eigenvectors (columns, right-handed orthonormal) of a symmetric 3x3 matrix by cyclic
  !> Jacobi rotations; a few sweeps reach rounding level.
  pure subroutine jacobi_eigenvectors(a_in, v)
    real(dp), intent(in) :: a_in(3, 3)
    real(dp), intent(out) :: v(3, 3)
    real(dp) :: a(3, 3), theta, t, c, s, apq, app, aqq, off, scale
    real(dp) :: col(3)
    integer :: sweep, p, q, r
    a = a_in
    v = reshape([1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp, 1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp, 1.0_dp], [3, 3])
    scale = abs(a(1, 1)) + abs(a(2, 2)) + abs(a(3, 3))
    if (scale <= 0.0_dp) return
    do sweep = 1, 30
      off = abs(a(1, 2)) + abs(a(1, 3)) + abs(a(2, 3))
      if (off <= 1.0e-15_dp*scale) exit
      do p = 1, 2
        do q = p + 1, 3
          apq = a(p, q)
          if (abs(apq) <= 1.0e-300_dp) cycle
          app = a(p, p)
          aqq = a(q, q)
          theta = (aqq - app)/(2.0_dp*apq)
          t = sign(1.0_dp, theta)/(abs(theta) + sqrt(theta*theta + 1.0_dp))
          c = 1.0_dp/sqrt(t*t + 1.0_dp)
          s = t*c
          do r = 1, 3
            col(r) = a(r, p)
            a(r, p) = c*col(r) - s*a(r, q)
            a(r, q) = s*col(r) + c*a(r, q)
          end do
          do r = 1, 3
            col(r) = a(p, r)
            a(p, r) = c*col(r) - s*a(q, r)
            a(q, r) = s*col(r) + c*a(q, r)
          end do
          do r = 1, 3
            col(r) = v(r, p)
            v(r, p) = c*col(r) - s*v(r, q)
            v(r, q) = s*col(r) + c*v(r, q)
          end do
        end do
      end do
    end do
    ! re-orthonormalise (Gram-Schmidt) so the box frame is a rotation to rounding
    v(:, 1) = v(:, 1)/norm2(v(:, 1))
    v(:, 2) = v(:, 2) - dot_product(v(:, 1), v(:, 2))*v(:, 1)
    v(:, 2) = v(:, 2)/norm2(v(:, 2))
    v(:, 3) = cross(v(:, 1), v(:, 2))
  end subroutine jacobi_eigenvectors

  !> Each vertex goes to the first slot that has it. Each edge goes to the first slot that
  !> has it; it is sharp unless exactly two faces share it and they are coplanar.
  subroutine assign_owners(self)
    type(skd_tree_t), intent(inout) :: self
    integer, allocatable :: seen(:), code(:)
    integer(i8), allocatable :: key(:)
    integer :: slot, k, n, i, j, g, owner, other
    integer(i8) :: na, nb, stride
    logical :: sharp
    n = 3*self%n_faces
    allocate (seen(self%n_mesh_nodes), key(n), code(n))
    seen = 0
    self%flags = 0
    stride = int(self%n_mesh_nodes, i8) + 1_i8
    do slot = 1, self%n_faces
      do k = 1, 3
        if (seen(self%tri_nodes(k, slot)) == 0) then
          seen(self%tri_nodes(k, slot)) = slot
          self%flags(slot) = ibset(self%flags(slot), k - 1)
        end if
        na = self%tri_nodes(k, slot)
        nb = self%tri_nodes(mod(k, 3) + 1, slot)
        key(3*(slot - 1) + k) = min(na, nb)*stride + max(na, nb)
        code(3*(slot - 1) + k) = 3*(slot - 1) + k - 1
      end do
    end do
    call sort_keys(key, code)
    i = 1
    do while (i <= n)
      j = i
      do while (j < n)
        if (key(j + 1) /= key(i)) exit
        j = j + 1
      end do
      ! codes i..j share one edge; the smallest code (first slot) owns it
      owner = minval(code(i:j))
      sharp = .true.
      if (j - i == 1) then
        other = maxval(code(i:j))
        sharp = dot_product(self%normal(:, owner/3 + 1), self%normal(:, other/3 + 1)) < flat_cosine
      end if
      slot = owner/3 + 1
      g = mod(owner, 3) + 1
      self%flags(slot) = ibset(self%flags(slot), g + 2)
      if (sharp) then
        do k = i, j
          slot = code(k)/3 + 1
          g = mod(code(k), 3) + 1
          self%flags(slot) = ibset(self%flags(slot), g + 5)
        end do
      end if
      i = j + 1
    end do
  end subroutine assign_owners

  !> Bottom-up merge sort of key with its payload code (stable, O(n log n)).
  subroutine sort_keys(key, code)
    integer(i8), intent(inout) :: key(:)
    integer, intent(inout) :: code(:)
    integer(i8), allocatable :: kt(:)
    integer, allocatable :: ct(:)
    integer :: n, width, lo, mid, hi, i, j, o
    n = size(key)
    allocate (kt(n), ct(n))
    width = 1
    do while (width < n)
      lo = 1
      do while (lo <= n)
        mid = min(lo + width - 1, n)
        hi = min(lo + 2*width - 1, n)
        i = lo
        j = mid + 1
        o = lo
        do while (o <= hi)
          if (j > hi) then
            kt(o) = key(i); ct(o) = code(i); i = i + 1
          else if (i > mid) then
            kt(o) = key(j); ct(o) = code(j); j = j + 1
          else if (key(j) < key(i)) then
            kt(o) = key(j); ct(o) = code(j); j = j + 1
          else
            kt(o) = key(i); ct(o) = code(i); i = i + 1
          end if
          o = o + 1
        end do
        lo = lo + 2*width
      end do
      key = kt
      code = ct
      width = 2*width
    end do
  end subroutine sort_keys

  pure function unit_normal(t) result(nrm)
    real(dp), intent(in) :: t(3, 3)
    real(dp) :: nrm(3), length
    nrm = cross(t(:, 2) - t(:, 1), t(:, 3) - t(:, 1))
    length = norm2(nrm)
    if (length > 0.0_dp) then
      nrm = nrm/length
    else
      nrm = 0.0_dp
    end if
  end function unit_normal

end module skd_tree
