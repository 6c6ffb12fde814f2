!> Times the stages of loading one mesh file as ricochet does for a &body with shape =
!> 'mesh': read and parse, weld, topology, self-intersection check (mesh_io's stats), then
!> mass properties and principal frame (make_mesh_shape) and the SKD-tree.
!> Usage: bench_mesh_load FILE (e.g. the torus of tests/regression/check_mesh_stress.py).
program bench_mesh_load
  use kinds, only: dp
  use mesh, only: mesh_t
  use mesh_io, only: read_mesh_file, mesh_read_stats_t
  use shape, only: shape_t
  use shape_factory, only: make_mesh_shape
  use error_status, only: error_t
  implicit none
  character(len=4096) :: path
  type(mesh_t) :: m
  type(shape_t) :: s
  type(error_t) :: err
  type(mesh_read_stats_t) :: stats
  real(dp) :: t0, t_shape, t_tree

  call get_command_argument(1, path)
  if (len_trim(path) == 0) error stop 'usage: bench_mesh_load FILE'
  call read_mesh_file(trim(path), m, err, stats=stats)
  if (err%failed()) then
    write (*, '(a)') 'error: '//err%message
    error stop 1
  end if
  t0 = now()
  call make_mesh_shape(m, 'bench', s, err)
  t_shape = now() - t0
  if (err%failed()) error stop 'make_mesh_shape failed'
  t0 = now()
  call s%tree%build(s%mesh, err)
  t_tree = now() - t0
  write (*, '(a,i0,a,i0,a,i0,a)') 'faces ', m%n_faces, ', nodes ', m%n_nodes, ' (', stats%n_merged_vertices, &
    ' file vertices welded)'
  write (*, '(a,f8.3,a)') 'read + parse        ', stats%seconds_parse, ' s'
  write (*, '(a,f8.3,a)') 'weld                ', stats%seconds_weld, ' s'
  write (*, '(a,f8.3,a)') 'topology            ', stats%seconds_topology, ' s'
  write (*, '(a,f8.3,a,i0,a)') 'self-intersection   ', stats%seconds_self_intersection, ' s (', &
    stats%n_pair_tests, ' pair tests)'
  write (*, '(a,f8.3,a)') 'mass properties     ', t_shape, ' s'
  write (*, '(a,f8.3,a,i0,a)') 'SKD-tree            ', t_tree, ' s (', s%tree%n_boxes, ' boxes)'
contains
  real(dp) function now()
    integer(8) :: c, r
    call system_clock(c, r)
    now = real(c, dp)/real(r, dp)
  end function now
end program bench_mesh_load
