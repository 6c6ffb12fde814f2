!> Benchmark of the closest-point query (mesh_mesh_distance through SKD-trees) for meshes of
!> 12 to ~100,000 triangles at separations from touching to far, with the speed-up over
!> brute force where brute force is affordable. Writes, into the folder given as the first
!> argument (default "."), the meshes (OBJ), the poses (poses.txt) and the timings
!> (ricochet_times.csv), so tools/bench_closest_points.py can time coal on exactly the same
!> meshes and poses.
!>
!> Built by tools/bench_closest_points.py against a Release build (or the CMake target in
!> tools/bench/CMakeLists.txt).
program bench_closest_points
  use, intrinsic :: iso_fortran_env, only: dp => real64, i8 => int64, output_unit
  use mesh, only: mesh_t
  use error_status, only: error_t
  use skd_tree, only: skd_tree_t
  use mesh_distance, only: mesh_mesh_distance, mesh_mesh_distance_brute, distance_result_t, query_stats_t
  use mesh_fixtures
  implicit none
  integer, parameter :: n_cases = 7, n_gaps = 4, n_poses = 5
  real(dp), parameter :: gaps(n_gaps) = [1.0e-4_dp, 1.0e-2_dp, 1.0e-1_dp, 1.0_dp]   ! [m]
  type(mesh_t) :: ma, mb
  type(skd_tree_t) :: ta, tb
  type(error_t) :: err
  type(distance_result_t) :: r, rb
  type(query_stats_t) :: stats
  character(len=512) :: folder
  character(len=64) :: name_a, name_b
  integer :: c, g, p, u_pose, u_time, n_rep, k, seed_size
  integer, allocatable :: seed(:)
  real(dp) :: xa(3), qa(4), xb(3), qb(4), dir(3), t_fast, t_brute, build_time, sum_time, sum_prim
  integer(i8) :: count0, count1, rate

  folder = '.'
  if (command_argument_count() >= 1) call get_command_argument(1, folder)
  call random_seed(size=seed_size)
  allocate (seed(seed_size))
  seed = 4242
  call random_seed(put=seed)
  open (newunit=u_pose, file=trim(folder)//'/poses.txt', status='replace', action='write')
  open (newunit=u_time, file=trim(folder)//'/ricochet_times.csv', status='replace', action='write')
  write (u_time, '(a)') 'case,mesh_a,faces_a,mesh_b,faces_b,gap,pose,distance,time_us,brute_time_us,box_pairs,'// &
    'primitive_tests,build_ms'
  do c = 1, n_cases
    call make_case(c, ma, mb, name_a, name_b)
    call system_clock(count0, rate)
    call ta%build(ma, err)
    call tb%build(mb, err)
    call system_clock(count1)
    build_time = 1.0e3_dp*real(count1 - count0, dp)/real(rate, dp)
    call write_obj(trim(folder)//'/'//trim(name_a)//'.obj', ma)
    call write_obj(trim(folder)//'/'//trim(name_b)//'.obj', mb)
    do g = 1, n_gaps
      sum_time = 0.0_dp
      sum_prim = 0.0_dp
      do p = 1, n_poses
        qa = random_unit_quaternion()
        qb = random_unit_quaternion()
        xa = 0.0_dp
        dir = random_unit_vector()
        call place(dir, gaps(g), xa, qa, xb, qb)
        write (u_pose, '(i0,1x,a,1x,a,1x,es10.3,1x,i0,14(1x,es24.16))') c, trim(name_a), trim(name_b), gaps(g), p, &
          xa, qa, xb, qb
        ! time: repeat until 0.05 s of work
        n_rep = 0
        call system_clock(count0)
        do
          do k = 1, 10
            call mesh_mesh_distance(ta, xa, qa, tb, xb, qb, r)
          end do
          n_rep = n_rep + 10
          call system_clock(count1)
          if (real(count1 - count0, dp)/real(rate, dp) > 0.05_dp) exit
        end do
        t_fast = 1.0e6_dp*real(count1 - count0, dp)/real(rate, dp)/n_rep
        stats = query_stats_t()
        call mesh_mesh_distance(ta, xa, qa, tb, xb, qb, r, stats)
        t_brute = -1.0_dp
        if (real(ma%n_faces, dp)*real(mb%n_faces, dp) <= 3.0e7_dp .and. p == 1) then
          call system_clock(count0)
          call mesh_mesh_distance_brute(ma, xa, qa, mb, xb, qb, rb)
          call system_clock(count1)
          t_brute = 1.0e6_dp*real(count1 - count0, dp)/real(rate, dp)
          if (abs(rb%distance - r%distance) > 1.0e-12_dp*rb%distance + 1.0e-14_dp) &
            write (output_unit, '(a,2es24.16)') 'MISMATCH with brute force: ', r%distance, rb%distance
        end if
        sum_time = sum_time + t_fast
        sum_prim = sum_prim + real(stats%primitive_tests, dp)
        write (u_time, '(i0,",",a,",",i0,",",a,",",i0,",",es10.3,",",i0,",",es24.16,",",es12.5,",",es12.5,' &
               //'",",i0,",",i0,",",f10.2)') c, trim(name_a), ma%n_faces, trim(name_b), mb%n_faces, gaps(g), p, &
          r%distance, t_fast, t_brute, stats%box_pairs, stats%primitive_tests, build_time
      end do
      write (output_unit, '(a,1x,i6,1x,a,1x,i6,a,es9.2,a,f12.2,a,f12.0)') trim(name_a), ma%n_faces, trim(name_b), &
        mb%n_faces, '  gap ', gaps(g), '  mean ', sum_time/n_poses, ' us  primitive tests ', sum_prim/n_poses
    end do
  end do
  close (u_pose)
  close (u_time)

contains

  subroutine make_case(c, ma, mb, name_a, name_b)
    integer, intent(in) :: c
    type(mesh_t), intent(out) :: ma, mb
    character(len=*), intent(out) :: name_a, name_b
    select case (c)
    case (1)
      call box_fixture([0.5_dp, 0.4_dp, 0.3_dp], ma); name_a = 'box12'
      call box_fixture([0.5_dp, 0.4_dp, 0.3_dp], mb); name_b = 'box12'
    case (2)
      call icosphere_fixture(0.5_dp, 1, ma); name_a = 'ico80'
      call torus_fixture(0.4_dp, 0.15_dp, 8, 6, mb); name_b = 'torus96'
    case (3)
      call icosphere_fixture(0.5_dp, 3, ma); name_a = 'ico1280'
      call torus_fixture(0.4_dp, 0.15_dp, 32, 16, mb); name_b = 'torus1024'
    case (4)
      call blob_fixture(0.5_dp, 4, 0.2_dp, [0.3_dp, 1.1_dp, 2.0_dp], ma); name_a = 'blob5120'
      call torus_fixture(0.4_dp, 0.15_dp, 64, 32, mb); name_b = 'torus4096'
    case (5)
      call icosphere_fixture(0.5_dp, 5, ma); name_a = 'ico20480'
      call torus_fixture(0.4_dp, 0.15_dp, 128, 64, mb); name_b = 'torus16384'
    case (6)
      call blob_fixture(0.5_dp, 5, 0.2_dp, [0.3_dp, 1.1_dp, 2.0_dp], ma); name_a = 'blob20480'
      call blob_fixture(0.5_dp, 5, 0.25_dp, [1.0_dp, 0.2_dp, 0.5_dp], mb); name_b = 'blob20480b'
    case default
      call blob_fixture(0.5_dp, 6, 0.2_dp, [0.3_dp, 1.1_dp, 2.0_dp], ma); name_a = 'blob81920'
      call torus_fixture(0.4_dp, 0.15_dp, 256, 200, mb); name_b = 'torus102400'
    end select
  end subroutine make_case

  !> B along dir from A with the given gap [m]: sphere tracing from far away. The distance
  !> changes by at most the translation, so stepping by (distance - gap) never overshoots.
  subroutine place(dir, gap, xa, qa, xb, qb)
    real(dp), intent(in) :: dir(3), gap, xa(3), qa(4), qb(4)
    real(dp), intent(out) :: xb(3)
    real(dp) :: s
    integer :: it
    type(distance_result_t) :: res
    s = ta%radius + tb%radius + norm2(ta%box(1:3, 1)) + norm2(tb%box(1:3, 1)) + gap + 1.0_dp
    do it = 1, 500
      xb = xa + s*dir
      call mesh_mesh_distance(ta, xa, qa, tb, xb, qb, res)
      if (res%distance - gap < 1.0e-3_dp*gap) exit
      s = s - (res%distance - gap)
    end do
  end subroutine place

  subroutine write_obj(path, m)
    character(len=*), intent(in) :: path
    type(mesh_t), intent(in) :: m
    integer :: u, i
    open (newunit=u, file=path, status='replace', action='write')
    do i = 1, m%n_nodes
      write (u, '(a,3(1x,es24.16))') 'v', m%nodes(:, i)
    end do
    do i = 1, m%n_faces
      write (u, '(a,3(1x,i0))') 'f', m%faces(:, i)
    end do
    close (u)
  end subroutine write_obj

end program bench_closest_points
