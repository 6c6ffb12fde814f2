!> Real published meshes (tests/data/meshes, see its README): the closed ones load, weld,
!> and give a closed, consistently oriented surface of the expected topology and a positive
!> volume equal to an independent computation, and do not cross themselves; the open ones
!> (stanford-bunny, suzanne) are refused naming the file, the defect, how many edges and
!> the first one, and the self-intersecting cow naming the first pair of faces that cross.
program test_real_meshes
  use kinds, only: dp
  use mesh, only: mesh_t
  use mesh_io, only: read_mesh_file, mesh_read_stats_t
  use mesh_topology, only: signed_volume, vertex_fan_count, component_count
  use error_status, only: error_t, ERR_MESH
  use assertions
  implicit none
  type(mesh_t) :: m
  type(error_t) :: err

  ! Expected counts were measured with this reader and cross-checked with an independent
  ! Python script (numpy, no welding); volumes are that script's sum of det(p1,p2,p3)/6
  ! about the origin. Genus g from n_fans - E + F = 2 - 2g (one component each).
  !           name           V      E      F   fans  genus  volume
  call closed('spot',        2930,  8784,  5856,  2930, 0, 0.7182587880998647_dp)
  call closed('fandisk',     6475, 19419, 12946,  6475, 0, 20.243374882839433_dp)
  ! rocker-arm: genus 1 (V - E + F = 0). The README calls it a triangle soup, but this
  ! copy already shares its vertices: welding merges none (checked below).
  call closed('rocker-arm', 10044, 30132, 20088, 10044, 1, 0.04251362358052909_dp)
  call closed('cheburashka', 6669, 20001, 13334,  6669, 0, 0.054381619531243736_dp)
  call closed('homer',       6002, 18000, 12000,  6002, 0, 0.021241926893821667_dp)

  ! Coordinates are converted exactly like the compiler's own reading of the literal
  ! (both correctly rounded): spot's first vertex, compared bit for bit.
  call err%clear()
  call read_mesh_file(test_data_path('meshes/spot.obj'), m, err)
  call check(all(m%nodes(:, 1) == [0.348799_dp, -0.334989_dp, -0.0832331_dp]), 'spot vertex 1 read exactly')

  ! cow: closed and oriented (one pinched vertex, file vertex 254), but its surface crosses
  ! itself near (-3.71, 1.5, -0.12): 81 pairs of faces cross, the first (by face number)
  ! triangles 201 and 1718, both counts checked independently (numpy: the mesh edges that
  ! pierce a face they are not incident to, 76 of them, and the face pairs they give).
  call err%clear()
  call read_mesh_file(test_data_path('meshes/cow.obj'), m, err)
  call check(err%code == ERR_MESH, 'cow refused with ERR_MESH')
  call check_error(err%code, err%message, [character(len=80) :: 'cow.obj', 'intersects itself', &
                   '81 pair(s) of faces cross', 'triangle 201 (line 3117) and triangle 1718 (line 4634)'], &
                   'cow: self-intersecting, the first crossing pair named')
  call check(.not. allocated(m%nodes), 'refused cow leaves the mesh empty')

  ! stanford-bunny: 223 boundary edges (holes in the scan), the first in (smaller node,
  ! larger node) order joining file vertices 1885 and 18289 (checked independently).
  call err%clear()
  call read_mesh_file(test_data_path('meshes/stanford-bunny.obj'), m, err)
  call check(err%code == ERR_MESH, 'stanford-bunny refused with ERR_MESH')
  call check_error(err%code, err%message, [character(len=80) :: 'stanford-bunny.obj', 'open surface', &
                   '223 boundary edge(s)', 'nodes 1885 (-5.750000000E-2, 5.882700000E-2, 2.126000000E-2) and 18289 ('], &
                   'stanford-bunny: open, 223 boundary edges, the first named')
  call check(index(err%message, 'non-manifold') == 0 .and. index(err%message, 'orientation') == 0, &
             'stanford-bunny: only the holes are reported')
  call check(.not. allocated(m%nodes), 'refused bunny leaves the mesh empty')

  ! suzanne: quads written v//vn; 42 boundary edges (eye holes) and one edge (file
  ! vertices 71-139) shared by 4 faces.
  call err%clear()
  call read_mesh_file(test_data_path('meshes/suzanne.obj'), m, err)
  call check_error(err%code, err%message, [character(len=80) :: 'suzanne.obj', 'open surface', &
                   '42 boundary edge(s)', 'non-manifold', '1 edge(s) used by more than two faces', &
                   'edge between nodes 71 (', ' and 139 (', 'used by 4 faces'], 'suzanne: open and non-manifold, named')

  call test_finish()

contains

  subroutine closed(name, n_nodes, n_edges, n_faces, n_fans, genus, volume)
    character(len=*), intent(in) :: name
    integer, intent(in) :: n_nodes, n_edges, n_faces, n_fans, genus
    real(dp), intent(in) :: volume
    type(mesh_read_stats_t) :: stats
    call err%clear()
    call read_mesh_file(test_data_path('meshes/'//name//'.obj'), m, err, stats=stats)
    call check(err%ok(), name//' loads')
    if (err%failed()) then
      call check(.false., name//': '//err%message)
      return
    end if
    call check(m%n_nodes == n_nodes .and. m%n_edges == n_edges .and. m%n_faces == n_faces, &
               name//': V, E, F as expected')
    call check(stats%n_merged_vertices == 0 .and. stats%n_degenerate_triangles == 0 .and. stats%n_unused_nodes == 0, &
               name//': nothing welded, dropped or unused')
    call check(component_count(m) == 1, name//': one component')
    call check(vertex_fan_count(m) == n_fans, name//': vertex fans')
    call check(n_fans - m%n_edges + m%n_faces == 2 - 2*genus, name//': genus '//char(iachar('0') + genus))
    ! Closed: every edge has its two faces (no zero entries).
    call check(all(m%edge_faces > 0), name//': every edge has two faces')
    ! Same sum in another order and about another origin: round-off ~1e-14 relative at
    ! these sizes (2e4 terms), so 1e-12 separates a wrong face or node from rounding.
    call check(signed_volume(m) > 0.0_dp, name//': positive volume (outward normals)')
    call check_close(signed_volume(m), volume, 1.0e-12_dp, name//': volume')
  end subroutine closed

end program test_real_meshes
