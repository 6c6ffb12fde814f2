!> Exact mass properties of a solid bounded by a closed, outward-oriented triangle surface.
!>
!> By the divergence theorem the solid is the signed sum of the tetrahedra joining a
!> reference point o to every face (Tonon, J. Math. Stat. 1 (2004) 8-11; the same
!> identities as Mirtich 1996 and Eberly's "Polyhedral Mass Properties (Revisited)").
!> For the tetrahedron (o, a, b, c), with a, b, c relative to o and v = det[a b c]/6:
!>   integral dV         = v
!>   integral x dV       = v (a + b + c)/4
!>   integral x x^T dV   = v/20 (a a^T + b b^T + c c^T + s s^T),  s = a + b + c.
!> These are exact polynomial identities, so the only error is round-off. o is the mean of
!> the nodes, which lies near the body: the terms then have the size of the body and the
!> second moments about the centroid are not a small difference of large numbers.
module mass_properties
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kinds, only: dp
  use mesh, only: mesh_t
  use error_status, only: error_t, ERR_MESH
  use string_utils, only: str
  implicit none
  private
  public :: polyhedron_mass_properties, inertia_defect

  !> A closed mesh whose volume is below this factor of its bounding-box diagonal cubed is
  !> flat (all faces in one plane up to round-off): its "volume" is round-off noise of
  !> relative size ~1e-16 times the face count, not a body.
  real(dp), parameter :: flat_volume_factor = 1.0e-12_dp
  !> Slack of the triangle inequality of principal moments, relative to their sum. A flat
  !> plate meets I3 = I1 + I2 exactly, so computed moments of thin bodies sit on the bound
  !> up to the round-off of the face sums and of the eigen-decomposition: about eps = 1e-16
  !> per face term, 1e-10 for 10^6 faces; 1e-9 stays above that and far below any real
  !> violation (a negative mass somewhere makes one of a few per cent or more).
  real(dp), parameter :: inertia_slack = 1.0e-9_dp

contains

  !> volume [m^3], centroid(3) [m] and inertia(3,3) [m^5], the inertia tensor about the
  !> centroid per unit density, I = integral of (r.r 1 - r r^T) dV, of the solid bounded by
  !> the closed outward-oriented surface m. Fails (ERR_MESH) for a mesh without faces, with
  !> face indices out of range, or whose volume is not positive (inward faces, open or flat
  !> mesh).
  subroutine polyhedron_mass_properties(m, volume, centroid, inertia, err)
    type(mesh_t), intent(in) :: m
    real(dp), intent(out) :: volume
    real(dp), intent(out) :: centroid(3)
    real(dp), intent(out) :: inertia(3, 3)
    type(error_t), intent(out) :: err
    real(dp) :: origin(3), a(3), b(3), c(3), s(3), v, first(3), second(3, 3), g(3), lower(3), upper(3)
    real(dp) :: diagonal
    integer :: f, i, j

    volume = 0.0_dp
    centroid = 0.0_dp
    inertia = 0.0_dp
    if (m%n_faces <= 0 .or. m%n_nodes <= 0) then
      call err%set(ERR_MESH, 'mesh '''//source_of(m)//''' has no faces: it encloses no volume')
      return
    end if
    if (minval(m%faces(:, 1:m%n_faces)) < 1 .or. maxval(m%faces(:, 1:m%n_faces)) > m%n_nodes) then
      call err%set(ERR_MESH, 'mesh '''//source_of(m)//''': a face refers to a node outside 1..'// &
                   str(m%n_nodes))
      return
    end if
    if (.not. all(ieee_is_finite(m%nodes(:, 1:m%n_nodes)))) then
      call err%set(ERR_MESH, 'mesh '''//source_of(m)//''': a node coordinate is NaN or infinite')
      return
    end if

    origin = sum(m%nodes(:, 1:m%n_nodes), dim=2)/real(m%n_nodes, dp)
    first = 0.0_dp
    second = 0.0_dp
    do f = 1, m%n_faces
      a = m%nodes(:, m%faces(1, f)) - origin
      b = m%nodes(:, m%faces(2, f)) - origin
      c = m%nodes(:, m%faces(3, f)) - origin
      ! Six times the signed volume of the tetrahedron (origin, a, b, c).
      v = a(1)*(b(2)*c(3) - b(3)*c(2)) + a(2)*(b(3)*c(1) - b(1)*c(3)) + a(3)*(b(1)*c(2) - b(2)*c(1))
      s = a + b + c
      volume = volume + v
      first = first + v*s
      do j = 1, 3
        do i = j, 3
          second(i, j) = second(i, j) + v*(a(i)*a(j) + b(i)*b(j) + c(i)*c(j) + s(i)*s(j))
        end do
      end do
    end do
    ! Apply the constant factors once: 1/6 (volume), 1/24 (first moment), 1/120 (second).
    volume = volume/6.0_dp
    first = first/24.0_dp
    second = second/120.0_dp
    do j = 1, 3
      do i = 1, j - 1
        second(i, j) = second(j, i)
      end do
    end do

    call m%bounds(lower, upper)
    diagonal = norm2(upper - lower)
    if (.not. (volume > flat_volume_factor*diagonal**3)) then
      call err%set(ERR_MESH, 'mesh '''//source_of(m)//''' encloses volume '//str(volume)// &
                   ' m^3 (bounding-box diagonal '//str(diagonal)//' m): the volume must be positive; '// &
                   'the faces may be oriented inward, or the mesh is open or flat')
      volume = 0.0_dp
      return
    end if

    g = first/volume
    centroid = origin + g
    ! Second moments about the centroid (parallel-axis shift), then I = tr(C) 1 - C.
    do j = 1, 3
      do i = 1, 3
        second(i, j) = second(i, j) - volume*g(i)*g(j)
      end do
    end do
    inertia = -second
    do i = 1, 3
      inertia(i, i) = inertia(i, i) + second(1, 1) + second(2, 2) + second(3, 3)
    end do
  end subroutine polyhedron_mass_properties

  !> Why three principal moments moments(3) [kg m^2] cannot be a rigid body's, or '' when
  !> they can: a body of positive mass has a positive definite inertia tensor (every moment
  !> > 0) and, each moment being a sum of m (y^2 + z^2)-like terms, no moment exceeds the
  !> sum of the other two (up to inertia_slack). Moments that fail come from no mass
  !> distribution at all: from a mesh, one whose shells count some volume negatively (a
  !> cavity shell outside the body, shells oriented against each other).
  pure function inertia_defect(moments) result(text)
    real(dp), intent(in) :: moments(3)
    character(len=:), allocatable :: text
    integer :: k
    text = ''
    if (.not. all(ieee_is_finite(moments))) then
      text = 'a principal moment is not a finite number'
    else if (any(moments <= 0.0_dp)) then
      text = 'not positive definite (every principal moment of a body with mass is > 0)'
    else
      do k = 1, 3
        if (moments(k) - (sum(moments) - moments(k)) > inertia_slack*sum(moments)) then
          text = 'moment '//str(k)//' exceeds the sum of the other two (no mass distribution has I'// &
                 str(k)//' > I'//str(mod(k, 3) + 1)//' + I'//str(mod(k + 1, 3) + 1)//')'
          return
        end if
      end do
    end if
  end function inertia_defect

  pure function source_of(m) result(text)
    type(mesh_t), intent(in) :: m
    character(len=:), allocatable :: text
    if (allocated(m%source)) then
      text = m%source
    else
      text = '(unnamed)'
    end if
  end function source_of

end module mass_properties
