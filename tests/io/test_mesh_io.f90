!> mesh_io on small files the test writes itself (in its run folder): OBJ in its corner
!> forms (a, a/t, a/t/n, a//n, negative indices, quads, CRLF), ASCII and binary STL (which
!> need welding), OFF; welding tolerance, degenerate triangles, scale; and each refusal
!> (syntax error with file and line, unknown extension, missing file, open surface...).
program test_mesh_io
  use, intrinsic :: iso_fortran_env, only: int16, int32, real32
  use kinds, only: dp
  use mesh, only: mesh_t
  use mesh_io, only: read_mesh_file, mesh_read_stats_t
  use mesh_topology, only: signed_volume
  use error_status, only: error_t, ERR_MESH, ERR_IO, ERR_INPUT
  use assertions
  implicit none
  character(len=*), parameter :: crlf = achar(13)
  ! Unit cube corners (node 1 + x + 2y + 4z at (x, y, z)) and its outward triangles.
  integer, parameter :: cube_faces(3, 12) = reshape([1, 3, 4, 1, 4, 2, 5, 6, 8, 5, 8, 7, 1, 2, 6, 1, 6, 5, &
                                                     3, 7, 8, 3, 8, 4, 1, 5, 7, 1, 7, 3, 2, 4, 8, 2, 8, 6], [3, 12])
  real(dp) :: corners(3, 8)
  type(mesh_t) :: m
  type(error_t) :: err
  type(mesh_read_stats_t) :: stats
  integer :: i

  do i = 1, 8
    corners(:, i) = real([mod(i - 1, 2), mod((i - 1)/2, 2), (i - 1)/4], dp)
  end do

  ! --- OBJ: every corner form, a quad, negative indices, ignored statements, CRLF, w ---
  call write_text('cube.obj', [character(len=60) :: '# unit cube'//crlf, 'mtllib cube.mtl'//crlf, &
                  'o cube'//crlf, 'v 0 0 0 1.0'//crlf, 'v 1.0 0 0'//crlf, 'v 0 1e0 0'//crlf, &
                  'v 1 1 0'//crlf, 'v 0 0 1'//crlf, 'v +1 0 1'//crlf, 'v 0.0 1 1.'//crlf, 'v 1 1 1'//crlf, &
                  'vt 0 0'//crlf, 'vt 1 0'//crlf, 'vt 1 1'//crlf, 'vt 0 1'//crlf, 'vn 0 0 -1'//crlf, &
                  'vn 0 0 1'//crlf, 'g sides'//crlf, 's off'//crlf, 'usemtl grey'//crlf, &
                  'f 1/1/1 3/2/1 4/3/1 2/4/1'//crlf, &      ! bottom: quad, a/t/n
                  'f 5//2 6//2 8//2'//crlf, 'f 5//2 8//2 7//2'//crlf, &   ! top: a//n
                  'f -8 -7 -3 -4'//crlf, &                  ! y = 0: quad, relative indices
                  'f 3/1 7/2 8/3 4/4'//crlf, &              ! y = 1: quad, a/t
                  'f 1 5 7 3'//crlf, &                      ! x = 0
                  'f 2 4 8 # comment'//crlf, 'f 2 8 6'//crlf, 'l 1 2'//crlf])
  call err%clear()
  call read_mesh_file('cube.obj', m, err, stats=stats)
  call check(err%ok(), 'OBJ cube read')
  call check(m%n_nodes == 8 .and. m%n_faces == 12 .and. m%n_edges == 18, 'OBJ cube: 8 nodes, 12 faces, 18 edges')
  call check(stats%n_file_vertices == 8 .and. stats%n_file_triangles == 12 .and. stats%n_merged_vertices == 0 &
             .and. stats%n_degenerate_triangles == 0 .and. stats%n_unused_nodes == 0, 'OBJ cube: stats')
  ! Corners 0 and 1 are exact, the volume about the centre 0.5 is a sum of exact terms.
  call check_close(signed_volume(m), 1.0_dp, 1.0e-14_dp, 'OBJ cube volume 1')
  call check(all(m%nodes == corners), 'OBJ cube: node order and coordinates as in the file')
  call check(all(m%faces == cube_faces), 'OBJ cube: fan triangulation (1,k,k+1) keeps orientation')
  call check(m%source == 'cube.obj', 'm%source is the path')
  ! Scale multiplies coordinates: volume scale^3 (2^3 exact).
  call err%clear()
  call read_mesh_file('cube.obj', m, err, scale=2.0_dp)
  call check(err%ok(), 'OBJ cube read with scale')
  call check_close(signed_volume(m), 8.0_dp, 1.0e-14_dp, 'scale 2: volume 8')
  call check(maxval(m%nodes) == 2.0_dp, 'scale 2: coordinates doubled')
  ! Extension is case-insensitive.
  call copy_text('cube.obj', 'CUBE2.OBJ')
  call err%clear()
  call read_mesh_file('CUBE2.OBJ', m, err)
  call check(err%ok() .and. m%n_faces == 12, 'upper-case .OBJ read')

  ! --- OBJ triangle soup: every triangle has its own vertices, some off by 1e-12 ---
  ! Welding tolerance is 1e-9 x diagonal (1.7e-9 here): 1e-12 is merged, giving the
  ! 8-node cube; the same soup off by 1e-6 is not merged and is an open surface.
  call write_soup_obj('soup.obj', 1.0e-12_dp)
  call err%clear()
  call read_mesh_file('soup.obj', m, err, stats=stats)
  call check(err%ok(), 'OBJ soup welded')
  call check(m%n_nodes == 8 .and. m%n_edges == 18, 'OBJ soup: 8 nodes, 18 edges after welding')
  call check(stats%n_file_vertices == 36 .and. stats%n_merged_vertices == 28, 'OBJ soup: 28 of 36 vertices merged')
  ! Nodes keep the first vertex of each cluster, off by at most 1e-12 per coordinate:
  ! the volume moves by at most ~6 faces x 1e-12, so 1e-11 relative.
  call check_close(signed_volume(m), 1.0_dp, 1.0e-11_dp, 'OBJ soup volume 1')
  call write_soup_obj('soup_far.obj', 1.0e-6_dp)
  call err%clear()
  call read_mesh_file('soup_far.obj', m, err)
  call check_error(err%code, err%message, [character(len=40) :: "'soup_far.obj'", 'open surface'], &
                   'vertices 1e-6 apart are not welded')

  ! --- Degenerate triangles are dropped and counted; their private node too ---
  call write_text('degenerate.obj', [character(len=40) :: 'v 0 0 0', 'v 1 0 0', 'v 0 1 0', 'v 1 1 0', &
                  'v 0 0 1', 'v 1 0 1', 'v 0 1 1', 'v 1 1 1', 'v 0.5 0 0', &
                  'f 1 3 4', 'f 1 4 2', 'f 5 6 8', 'f 5 8 7', 'f 1 2 6', 'f 1 6 5', 'f 3 7 8', 'f 3 8 4', &
                  'f 1 5 7', 'f 1 7 3', 'f 2 4 8', 'f 2 8 6', &
                  'f 1 2 1', &      ! repeated node
                  'f 1 9 2'])       ! collinear: zero area
  call err%clear()
  call read_mesh_file('degenerate.obj', m, err, stats=stats)
  call check(err%ok(), 'OBJ with degenerate triangles read')
  call check(stats%n_degenerate_triangles == 2 .and. stats%n_unused_nodes == 1 .and. m%n_faces == 12 &
             .and. m%n_nodes == 8, 'two degenerate triangles dropped, their extra node too')

  ! --- ASCII STL, inward (reversed) facets: welded and flipped outward ---
  call write_ascii_stl('cube_ascii.stl')
  call err%clear()
  call read_mesh_file('cube_ascii.stl', m, err, stats=stats)
  call check(err%ok(), 'ASCII STL cube read')
  call check(m%n_nodes == 8 .and. m%n_faces == 12 .and. m%n_edges == 18, 'ASCII STL: 8 nodes, 12 faces, 18 edges')
  call check(stats%n_file_vertices == 36 .and. stats%n_merged_vertices == 28, 'ASCII STL: 28 of 36 vertices merged')
  call check_close(signed_volume(m), 1.0_dp, 1.0e-14_dp, 'ASCII STL inward cube flipped to volume +1')

  ! --- binary STL, header beginning with "solid" (the size decides), scale 0.5 ---
  call write_binary_stl('cube_binary.stl', 12)
  call err%clear()
  call read_mesh_file('cube_binary.stl', m, err, scale=0.5_dp, stats=stats)
  call check(err%ok(), 'binary STL cube read')
  call check(m%n_nodes == 8 .and. m%n_faces == 12 .and. m%n_edges == 18, 'binary STL: 8 nodes, 12 faces, 18 edges')
  call check(stats%n_merged_vertices == 28, 'binary STL: 28 vertices merged')
  call check_close(signed_volume(m), 0.125_dp, 1.0e-14_dp, 'binary STL cube, scale 1/2: volume 1/8')
  ! The same file cut short: the size no longer matches the header's count, and although
  ! it begins with "solid" it holds binary data: refused as truncated, not parsed as ASCII.
  call write_binary_stl('cut.stl', 11)
  call err%clear()
  call read_mesh_file('cut.stl', m, err)
  call check_error(err%code, err%message, [character(len=40) :: "'cut.stl'", 'announces 12 triangles', &
                   '684 bytes', '634 bytes', 'truncated'], 'truncated binary STL refused')

  ! --- OFF: cube as quads (0-based), comments, counts on their own line ---
  call write_text('cube.off', [character(len=40) :: 'OFF', '# unit cube, 6 quads', '', '8 6 12', &
                  '0 0 0', '1 0 0', '0 1 0', '1 1 0', '0 0 1', '1 0 1', '0 1 1', '1 1 1  # last vertex', &
                  '4 0 2 3 1', '4 4 5 7 6', '4 0 1 5 4', '4 2 6 7 3', '4 0 4 6 2', '4 1 3 7 5 255 0 0'])
  call err%clear()
  call read_mesh_file('cube.off', m, err)
  call check(err%ok(), 'OFF cube read')
  call check(m%n_nodes == 8 .and. m%n_faces == 12 .and. m%n_edges == 18, 'OFF cube: 8 nodes, 12 faces, 18 edges')
  call check_close(signed_volume(m), 1.0_dp, 1.0e-14_dp, 'OFF cube volume 1')
  ! Tetrahedron with counts on the header line, decimal coordinates: 0.1 is not exact in
  ! binary, the volume 0.1^3/6 then carries a few ulp: 1e-14 relative.
  call write_text('tet.off', [character(len=40) :: 'OFF 4 4 6', '0 0 0', '0.1 0 0', '0 0.1 0', '0 0 0.1', &
                  '3 0 2 1', '3 0 1 3', '3 0 3 2', '3 1 2 3'])
  call err%clear()
  call read_mesh_file('tet.off', m, err)
  call check(err%ok() .and. m%n_edges == 6 .and. m%n_nodes - m%n_edges + m%n_faces == 2, 'OFF tetrahedron read')
  call check_close(signed_volume(m), 1.0e-3_dp/6.0_dp, 1.0e-14_dp, 'OFF tetrahedron volume')

  ! --- refusals ---
  call write_text('bad_syntax.obj', [character(len=20) :: 'v 0 0 0', '# comment', 'v 1 0 zero', 'v 0 1 0'])
  call expect_failure('bad_syntax.obj', [character(len=40) :: "mesh file 'bad_syntax.obj', line 3", "'zero'"], &
                      'OBJ syntax error names file and line', ERR_MESH)
  call write_text('bad_index.obj', [character(len=20) :: 'v 0 0 0', 'v 1 0 0', 'v 0 1 0', 'f 1 2 3', 'f 1 2 7'])
  call expect_failure('bad_index.obj', [character(len=40) :: "'bad_index.obj', line 5", 'vertex 7', &
                      'only 3 vertices'], 'OBJ face beyond the last vertex', ERR_MESH)
  call write_text('bad_zero.obj', [character(len=20) :: 'v 0 0 0', 'v 1 0 0', 'v 0 1 0', 'f 0 1 2'])
  call expect_failure('bad_zero.obj', [character(len=40) :: 'line 4', 'index 0'], 'OBJ index 0', ERR_MESH)
  call write_text('bad_relative.obj', [character(len=20) :: 'v 0 0 0', 'v 1 0 0', 'f -1 -2 -3'])
  call expect_failure('bad_relative.obj', [character(len=40) :: 'line 3', 'relative'], 'OBJ relative index too far', &
                      ERR_MESH)
  call write_text('bad_statement.obj', [character(len=20) :: 'v 0 0 0', 'curv 0 1 1 2'])
  call expect_failure('bad_statement.obj', [character(len=40) :: 'line 2', "'curv'"], 'unknown OBJ statement', ERR_MESH)
  call write_text('open.obj', [character(len=20) :: 'v 0 0 0', 'v 1 0 0', 'v 0 1 0', 'v 1 1 0', &
                  'v 0 0 1', 'v 1 0 1', 'v 0 1 1', 'v 1 1 1', 'f 1 3 4 2', 'f 1 2 6 5', 'f 3 7 8 4', &
                  'f 1 5 7 3', 'f 2 4 8 6'])
  call expect_failure('open.obj', [character(len=40) :: "mesh 'open.obj'", 'open surface', '4 boundary edge(s)'], &
                      'box without lid refused', ERR_MESH)
  call write_text('bad.stl', [character(len=30) :: 'solid x', ' facet normal 0 0 1', '  outer loop', &
                  '   vertex 0 0 0', '   vertex 1 0', '   vertex 0 1 0', '  endloop', ' endfacet', 'endsolid x'])
  call expect_failure('bad.stl', [character(len=40) :: "'bad.stl', line 6", 'expected a number'], &
                      'ASCII STL syntax error names the line', ERR_MESH)
  call write_text('unended.stl', [character(len=30) :: 'solid x', ' facet normal 0 0 1', '  outer loop', &
                  '   vertex 0 0 0', '   vertex 1 0 0', '   vertex 0 1 0', '  endloop', ' endfacet'])
  call expect_failure('unended.stl', [character(len=40) :: "'unended.stl'", "missing 'endsolid'"], &
                      'ASCII STL without endsolid', ERR_MESH)
  call write_text('garbage.stl', [character(len=100) :: repeat('x', 99), repeat('y', 99)])
  call expect_failure('garbage.stl', [character(len=40) :: "'garbage.stl'", 'not a valid STL'], &
                      'neither binary nor ASCII STL', ERR_MESH)
  call write_text('bad.off', [character(len=20) :: 'OFF', '3 1 0', '0 0 0', '1 0 0', '0 1 0', '3 0 1 3'])
  call expect_failure('bad.off', [character(len=40) :: "'bad.off', line 6", 'vertex 3', '0 to 2'], &
                      'OFF index out of range names the line', ERR_MESH)
  call write_text('short.off', [character(len=20) :: 'OFF', '4 4 0', '0 0 0', '1 0 0'])
  call expect_failure('short.off', [character(len=40) :: "'short.off'", '2 of the 4 vertices'], &
                      'OFF shorter than its counts', ERR_MESH)
  call write_text('noheader.off', [character(len=20) :: 'PLY', '3 1 0'])
  call expect_failure('noheader.off', [character(len=40) :: "'noheader.off', line 1", "'PLY'"], &
                      'OFF without header', ERR_MESH)
  call write_text('empty.obj', [character(len=1) :: ''])
  call expect_failure('empty.obj', [character(len=40) :: "'empty.obj'", 'no faces'], 'OBJ without faces', ERR_MESH)
  call write_text('cube.ply', [character(len=3) :: 'ply'])
  call expect_failure('cube.ply', [character(len=40) :: "'cube.ply'", "'.ply'", '.obj', '.stl', '.off'], &
                      'unknown extension lists the supported ones', ERR_INPUT)
  call expect_failure('no/such/mesh.obj', [character(len=40) :: "'no/such/mesh.obj'", 'does not exist'], &
                      'missing file names the path', ERR_IO)
  call err%clear()
  call read_mesh_file('cube.obj', m, err, scale=-1.0_dp)
  call check_error(err%code, err%message, [character(len=40) :: 'scale', 'positive'], 'negative scale refused')
  call check(.not. allocated(m%nodes), 'refused read leaves the mesh empty')

  call test_finish()

contains

  subroutine expect_failure(path, fragments, what, code)
    character(len=*), intent(in) :: path, fragments(:), what
    integer, intent(in) :: code
    type(mesh_t) :: mm
    type(error_t) :: e
    call read_mesh_file(path, mm, e)
    call check_error(e%code, e%message, fragments, what)
    call check(e%code == code, what//': error code')
  end subroutine expect_failure

  subroutine write_text(path, lines)
    character(len=*), intent(in) :: path, lines(:)
    integer :: u, k
    open (newunit=u, file=path, status='replace', action='write')
    do k = 1, size(lines)
      write (u, '(a)') trim(lines(k))
    end do
    close (u)
  end subroutine write_text

  subroutine copy_text(from, to)
    character(len=*), intent(in) :: from, to
    character(len=200) :: text
    integer :: u, v, ios
    open (newunit=u, file=from, status='old', action='read')
    open (newunit=v, file=to, status='replace', action='write')
    do
      read (u, '(a)', iostat=ios) text
      if (ios /= 0) exit
      write (v, '(a)') trim(text)
    end do
    close (u)
    close (v)
  end subroutine copy_text

  !> The cube as 12 triangles with 3 vertices each; vertex j of triangle t is moved by
  !> offset*(t+j mod 3 - 1) in x, so copies of one corner differ by up to 2*offset.
  subroutine write_soup_obj(path, offset)
    character(len=*), intent(in) :: path
    real(dp), intent(in) :: offset
    integer :: u, t, j
    open (newunit=u, file=path, status='replace', action='write')
    do t = 1, 12
      do j = 1, 3
        write (u, '(a,3es25.16)') 'v ', corners(:, cube_faces(j, t)) + [offset*(mod(t + j, 3) - 1), 0.0_dp, 0.0_dp]
      end do
      write (u, '(a,3(1x,i0))') 'f', 3*t - 2, 3*t - 1, 3*t
    end do
    close (u)
  end subroutine write_soup_obj

  !> Facets with reversed vertex order (inward normals), upper-case keywords in one facet,
  !> a nan normal in another (normals are not used).
  subroutine write_ascii_stl(path)
    character(len=*), intent(in) :: path
    integer :: u, t, j
    open (newunit=u, file=path, status='replace', action='write')
    write (u, '(a)') 'solid cube made by test_mesh_io'
    do t = 1, 12
      if (t == 5) then
        write (u, '(a)') '  FACET NORMAL 0 0 0', '    OUTER LOOP'
      else if (t == 7) then
        write (u, '(a)') '  facet normal nan nan nan', '    outer loop'   ! seen in the wild, ignored
      else
        write (u, '(a)') '  facet normal 0 0 0', '    outer loop'
      end if
      do j = 3, 1, -1
        write (u, '(a,3f5.1)') '      vertex ', corners(:, cube_faces(j, t))
      end do
      write (u, '(a)') '    endloop', '  endfacet'
    end do
    write (u, '(a)') 'endsolid cube made by test_mesh_io'
    close (u)
  end subroutine write_ascii_stl

  !> Binary STL of the cube's first n_written triangles, header claiming 12: with n_written
  !> < 12 the size no longer matches.
  subroutine write_binary_stl(path, n_written)
    character(len=*), intent(in) :: path
    integer, intent(in) :: n_written
    character(len=80) :: header
    integer :: u, t, j
    header = 'solid binary cube whose header starts like ASCII'
    open (newunit=u, file=path, status='replace', action='write', access='stream', form='unformatted')
    write (u) header, 12_int32
    do t = 1, n_written
      write (u) [0.0_real32, 0.0_real32, 0.0_real32]
      do j = 1, 3
        write (u) real(corners(:, cube_faces(j, t)), real32)
      end do
      write (u) 0_int16
    end do
    close (u)
  end subroutine write_binary_stl

end program test_mesh_io
