!> Convexity flag of shapes (it selects the tighter time-of-contact bound, so a wrong
!> "convex" would be unsafe): boxes, cylinders and icospheres are convex; an L-prism, a
!> torus and a non-convex blob are not.
program test_convexity
  use kinds, only: dp
  use error_status, only: error_t
  use mesh, only: mesh_t
  use mesh_topology, only: build_mesh_topology, is_convex
  use shape_builders, only: box_mesh, cylinder_mesh, icosphere_mesh, torus_mesh, l_shape_mesh, random_blob_mesh
  use assertions
  implicit none
  type(mesh_t) :: m
  type(error_t) :: err
  call box_mesh([1.0_dp, 2.0_dp, 0.01_dp], m); call topo()
  call check(is_convex(m), 'thin box is convex')
  call cylinder_mesh(0.5_dp, 2.0_dp, 64, m); call topo()
  call check(is_convex(m), 'cylinder is convex')
  call icosphere_mesh(1.0_dp, 4, m); call topo()
  call check(is_convex(m), 'icosphere (level 4) is convex')
  call l_shape_mesh([2.0_dp, 2.0_dp, 1.0_dp], 0.5_dp, m); call topo()
  call check(.not. is_convex(m), 'L-prism is not convex')
  call torus_mesh(1.0_dp, 0.3_dp, 32, 16, m); call topo()
  call check(.not. is_convex(m), 'torus is not convex')
  call random_blob_mesh(1.0_dp, 0.3_dp, 3, 12345, m); call topo()
  call check(.not. is_convex(m), 'blob (seed 12345, amplitude 0.3) is not convex')
  call box_mesh([1.0_dp, 1.0_dp, 1.0_dp], m)
  call check(.not. is_convex(m), 'without topology nothing is claimed convex')
  call test_finish()
contains
  subroutine topo()
    call build_mesh_topology(m, err)
    call check(err%ok(), 'topology of '//m%source)
  end subroutine topo
end program test_convexity
