!> Surfaces of bodies in world coordinates for output: the mesh of a mesh shape, or for an
!> analytic sphere an icosphere of fixed resolution (an icosahedron subdivided twice: 162
!> points, 320 triangles; the picture only, contact uses the exact sphere). No HDF5 here, so
!> the geometry is testable on its own and shared by any writer.
module surface_render
  use kinds, only: dp, i8
  use shape, only: shape_library_t, shape_t, SHAPE_SPHERE, SHAPE_MESH
  use body_state, only: bodies_t
  use quaternion, only: quat_to_matrix
  use vector_ops, only: cross
  implicit none
  private
  public :: surface_render_t, sphere_subdivisions

  !> 2 subdivisions: 320 triangles, facet centres at most 1.8 % inside the sphere (volume
  !> 3.4 % short): fine for pictures and cheap for 10^5 spheres.
  integer, parameter :: sphere_subdivisions = 2

  type :: surface_render_t
    integer :: n_sphere_points = 0
    integer :: n_sphere_triangles = 0
    real(dp), allocatable :: sphere_points(:, :)       !< (3, n) unit sphere
    integer, allocatable :: sphere_triangles(:, :)     !< (3, n) 1-based, outward CCW
  contains
    procedure :: init => render_init
    procedure :: shape_counts => render_shape_counts
    procedure :: count => render_count
    procedure :: build => render_build
  end type surface_render_t

contains

  subroutine render_init(self, subdivisions)
    class(surface_render_t), intent(inout) :: self
    integer, intent(in), optional :: subdivisions
    integer :: levels
    levels = sphere_subdivisions
    if (present(subdivisions)) levels = subdivisions
    call icosphere(levels, self%sphere_points, self%sphere_triangles)
    self%n_sphere_points = size(self%sphere_points, 2)
    self%n_sphere_triangles = size(self%sphere_triangles, 2)
  end subroutine render_init

  !> Points and triangles drawn for one shape.
  pure subroutine render_shape_counts(self, s, n_points, n_triangles)
    class(surface_render_t), intent(in) :: self
    type(shape_t), intent(in) :: s
    integer, intent(out) :: n_points, n_triangles
    if (s%kind == SHAPE_SPHERE) then
      n_points = self%n_sphere_points
      n_triangles = self%n_sphere_triangles
    else
      n_points = s%mesh%n_nodes
      n_triangles = s%mesh%n_faces
    end if
  end subroutine render_shape_counts

  !> Points and triangles of the owned bodies.
  pure subroutine render_count(self, bodies, shapes, n_points, n_triangles)
    class(surface_render_t), intent(in) :: self
    type(bodies_t), intent(in) :: bodies
    type(shape_library_t), intent(in) :: shapes
    integer(i8), intent(out) :: n_points, n_triangles
    integer :: i, np, nt
    n_points = 0
    n_triangles = 0
    do i = 1, bodies%n_owned
      call self%shape_counts(shapes%shapes(bodies%shape_id(i)), np, nt)
      n_points = n_points + np
      n_triangles = n_triangles + nt
    end do
  end subroutine render_count

  !> World surface of the owned bodies, sized by count: points(3, :) [m], triangles(3, :)
  !> as 0-based point indices counted from first_point (this rank's offset in the file),
  !> body_id(:) the gid of each triangle's body, velocity(3, :) of each point v + w x r [m/s].
  pure subroutine render_build(self, bodies, shapes, first_point, points, triangles, body_id, velocity)
    class(surface_render_t), intent(in) :: self
    type(bodies_t), intent(in) :: bodies
    type(shape_library_t), intent(in) :: shapes
    integer(i8), intent(in) :: first_point
    real(dp), intent(out) :: points(:, :), velocity(:, :)
    integer(i8), intent(out) :: triangles(:, :), body_id(:)
    integer :: i, k, np, nt, p0, t0
    real(dp) :: r(3, 3), arm(3)
    p0 = 0
    t0 = 0
    do i = 1, bodies%n_owned
      associate (s => shapes%shapes(bodies%shape_id(i)))
        call self%shape_counts(s, np, nt)
        r = quat_to_matrix(bodies%q(:, i))
        do k = 1, np
          if (s%kind == SHAPE_SPHERE) then
            arm = matmul(r, s%radius*self%sphere_points(:, k))
          else
            arm = matmul(r, s%mesh%nodes(:, k))
          end if
          points(:, p0 + k) = bodies%x(:, i) + arm
          velocity(:, p0 + k) = bodies%v(:, i) + cross(bodies%w(:, i), arm)
        end do
        do k = 1, nt
          if (s%kind == SHAPE_SPHERE) then
            triangles(:, t0 + k) = first_point + p0 + self%sphere_triangles(:, k) - 1
          else
            triangles(:, t0 + k) = first_point + p0 + s%mesh%faces(:, k) - 1
          end if
          body_id(t0 + k) = bodies%gid(i)
        end do
      end associate
      p0 = p0 + np
      t0 = t0 + nt
    end do
  end subroutine render_build

  !> Unit icosphere: icosahedron, each triangle split in four `levels` times with the new
  !> points pushed onto the sphere. Shared edges get one midpoint (found by a search over the
  !> edges made so far: a few hundred, built once per run).
  subroutine icosphere(levels, points, triangles)
    integer, intent(in) :: levels
    real(dp), allocatable, intent(out) :: points(:, :)
    integer, allocatable, intent(out) :: triangles(:, :)
    real(dp), parameter :: t = 1.6180339887498948482_dp   ! golden ratio
    integer, allocatable :: next(:, :), edge_key(:, :), edge_mid(:)
    integer :: level, f, n_points, n_faces, n_edges, a, b, c, ab, bc, ca, max_points
    real(dp) :: normal(3), centre(3)

    max_points = 10*4**levels + 2
    allocate (points(3, max_points))
    points(:, 1:12) = reshape([-1.0_dp, t, 0.0_dp, 1.0_dp, t, 0.0_dp, -1.0_dp, -t, 0.0_dp, 1.0_dp, -t, 0.0_dp, &
                               0.0_dp, -1.0_dp, t, 0.0_dp, 1.0_dp, t, 0.0_dp, -1.0_dp, -t, 0.0_dp, 1.0_dp, -t, &
                               t, 0.0_dp, -1.0_dp, t, 0.0_dp, 1.0_dp, -t, 0.0_dp, -1.0_dp, -t, 0.0_dp, 1.0_dp], &
                              [3, 12])
    do a = 1, 12
      points(:, a) = points(:, a)/norm2(points(:, a))
    end do
    n_points = 12
    triangles = reshape([1, 12, 6, 1, 6, 2, 1, 2, 8, 1, 8, 11, 1, 11, 12, &
                         2, 6, 10, 6, 12, 5, 12, 11, 3, 11, 8, 7, 8, 2, 9, &
                         4, 10, 5, 4, 5, 3, 4, 3, 7, 4, 7, 9, 4, 9, 10, &
                         5, 10, 6, 3, 5, 12, 7, 3, 11, 9, 7, 8, 10, 9, 2], [3, 20])
    n_faces = 20
    do level = 1, levels
      allocate (next(3, 4*n_faces), edge_key(2, 3*n_faces), edge_mid(3*n_faces))
      n_edges = 0
      do f = 1, n_faces
        a = triangles(1, f); b = triangles(2, f); c = triangles(3, f)
        ab = midpoint(a, b); bc = midpoint(b, c); ca = midpoint(c, a)
        next(:, 4*f - 3) = [a, ab, ca]
        next(:, 4*f - 2) = [b, bc, ab]
        next(:, 4*f - 1) = [c, ca, bc]
        next(:, 4*f) = [ab, bc, ca]
      end do
      call move_alloc(next, triangles)
      n_faces = 4*n_faces
      deallocate (edge_key, edge_mid)
    end do
    points = points(:, 1:n_points)
    ! Outward orientation by construction; made certain here since it is cheap (convex).
    do f = 1, n_faces
      centre = points(:, triangles(1, f)) + points(:, triangles(2, f)) + points(:, triangles(3, f))
      normal = cross(points(:, triangles(2, f)) - points(:, triangles(1, f)), &
                     points(:, triangles(3, f)) - points(:, triangles(1, f)))
      if (dot_product(normal, centre) < 0.0_dp) triangles(2:3, f) = triangles([3, 2], f)
    end do

  contains

    integer function midpoint(i, j)
      integer, intent(in) :: i, j
      integer :: e, lo, hi
      lo = min(i, j); hi = max(i, j)
      do e = 1, n_edges
        if (edge_key(1, e) == lo .and. edge_key(2, e) == hi) then
          midpoint = edge_mid(e)
          return
        end if
      end do
      n_points = n_points + 1
      points(:, n_points) = 0.5_dp*(points(:, lo) + points(:, hi))
      points(:, n_points) = points(:, n_points)/norm2(points(:, n_points))
      n_edges = n_edges + 1
      edge_key(:, n_edges) = [lo, hi]
      edge_mid(n_edges) = n_points
      midpoint = n_points
    end function midpoint

  end subroutine icosphere

end module surface_render
