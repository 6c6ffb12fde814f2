!> Refuses a deck whose bodies overlap at the start (surfaces crossing, touching, or one
!> inside the other), naming both bodies. Candidate pairs come from the bucket grid (one
!> ring, bounding spheres), so the cost grows with the number of bodies, not its square.
module overlap_check
  use kinds, only: dp, i8
  use error_status, only: error_t, ERR_INPUT, ERR_INTERNAL
  use string_utils, only: str
  use input_config, only: deck_t
  use shape, only: shape_library_t, SHAPE_SPHERE
  use body_state, only: bodies_t
  use bucket_grid, only: bucket_grid_t, choose_box_size
  use mesh_distance, only: distance_result_t, sphere_mesh_distance
  use contact_features, only: bodies_overlap, winding_number
  use quaternion, only: quat_rotate_inverse
  use pair_geometry, only: bounding_sphere_boxes
  use parallel_env, only: parallel_t
  implicit none
  private
  public :: check_initial_overlaps, nearby_pairs

contains

  !> bodies must hold every body of the run (all ranks check the same pairs, so all agree).
  !> With time present (&output check_overlaps: the same test on every output frame of a
  !> run), an overlap is reported as an interpenetration at that time.
  !> With par present (bodies then the same on every rank), the exact tests, the costly
  !> part, are shared: rank r tests the candidate pairs r + 1, r + 1 + n_ranks, ... and
  !> the first overlapping pair in candidate order is the smallest any rank found (one
  !> MPI_Allreduce MIN), so every rank reports the same pair as one rank does (collective).
  subroutine check_initial_overlaps(deck, shapes, bodies, err, time, par)
    type(deck_t), intent(in) :: deck
    type(shape_library_t), intent(in) :: shapes
    type(bodies_t), intent(in) :: bodies
    type(error_t), intent(inout) :: err
    real(dp), intent(in), optional :: time
    type(parallel_t), intent(in), optional :: par
    real(dp), allocatable :: lower(:, :), upper(:, :), extent(:)
    integer, allocatable :: pairs(:, :)
    real(dp) :: box_size
    integer :: n, k, n_pairs, rank, n_ranks
    integer(i8) :: found
    logical :: any_dynamic
    logical, allocatable :: static(:)

    n = bodies%n_owned
    if (n < 2) return
    rank = 0
    n_ranks = 1
    if (present(par)) then
      rank = par%rank
      n_ranks = par%n_ranks
    end if
    static = bodies%fixed(1:n) .and. .not. bodies%asleep(1:n)   ! asleep bodies are checked too
    allocate (lower(3, n), upper(3, n))
    call bounding_sphere_boxes(shapes, bodies, n, lower, upper)
    any_dynamic = .not. all(static)
    if (any_dynamic) then
      extent = pack(upper(1, :) - lower(1, :), .not. static)
    else
      extent = upper(1, :) - lower(1, :)
    end if
    ! (the same bodies on every rank give the same error, if any, on every rank)
    call choose_box_size(extent, 1.0_dp, box_size, err)
    if (err%failed()) return
    call nearby_pairs(shapes, bodies, box_size, pairs, n_pairs, err)
    if (err%failed()) return
    found = huge(1_i8)
    do k = 1 + rank, n_pairs, n_ranks
      if (static(pairs(1, k)) .and. static(pairs(2, k))) cycle   ! static scenery may touch
      if (pair_overlaps(shapes, bodies, pairs(1, k), pairs(2, k))) then
        found = k
        exit
      end if
    end do
    if (present(par)) found = par%min(found)
    if (found == huge(1_i8)) return
    k = int(found)
    if (present(time)) then
      call err%set(ERR_INTERNAL, deck%path//': bodies '//describe(deck, bodies, pairs(1, k))//' and '// &
                   describe(deck, bodies, pairs(2, k))//' interpenetrate at t = '//str(time)// &
                   ' s (found by &output check_overlaps): this is a bug, please report it with the deck')
      return
    end if
    call err%set(ERR_INPUT, deck%path//': bodies '//describe(deck, bodies, pairs(1, k))//' and '// &
                 describe(deck, bodies, pairs(2, k))//' overlap at the start (surfaces cross, touch, '// &
                 'or one is inside the other): move them apart')
  end subroutine check_initial_overlaps

  !> The pairs of bodies whose bounding spheres lie within one grid box (of box_size [m])
  !> of each other, from the bucket grid: the candidates of the overlap test and of the
  !> smallest initial gap (--check).
  subroutine nearby_pairs(shapes, bodies, box_size, pairs, n_pairs, err)
    type(shape_library_t), intent(in) :: shapes
    type(bodies_t), intent(in) :: bodies
    real(dp), intent(in) :: box_size
    integer, allocatable, intent(out) :: pairs(:, :)
    integer, intent(out) :: n_pairs
    type(error_t), intent(inout) :: err
    type(bucket_grid_t) :: grid
    real(dp), allocatable :: lower(:, :), upper(:, :)
    integer :: n, i
    n = bodies%n_owned
    n_pairs = 0
    allocate (pairs(2, 0), lower(3, n), upper(3, n))
    call bounding_sphere_boxes(shapes, bodies, n, lower, upper)
    call grid%init(box_size, err)
    if (err%failed()) return
    call grid%build(n, lower, upper, [(.false., i=1, n)], err)
    if (err%failed()) return
    call grid%candidate_pairs(1, [0.0_dp], pairs, n_pairs, err)
    call grid%free()
  end subroutine nearby_pairs

  function describe(deck, bodies, i) result(text)
    type(deck_t), intent(in) :: deck
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: i
    character(len=:), allocatable :: text
    text = "'"//trim(deck%bodies(bodies%group_id(i))%name)//"' (body "//str(bodies%gid(i))//', &body #'// &
           str(bodies%group_id(i))//' at line '//str(deck%bodies(bodies%group_id(i))%line)//')'
  end function describe

  !> Spheres overlap when their gap is negative (touching spheres are a valid start, e.g. a
  !> Newton's cradle); mesh pairs when their surfaces meet or one contains the other.
  logical function pair_overlaps(shapes, bodies, i, j) result(overlap)
    type(shape_library_t), intent(in) :: shapes
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: i, j
    type(distance_result_t) :: d
    associate (si => shapes%shapes(bodies%shape_id(i)), sj => shapes%shapes(bodies%shape_id(j)))
      if (si%kind == SHAPE_SPHERE .and. sj%kind == SHAPE_SPHERE) then
        overlap = norm2(bodies%x(:, j) - bodies%x(:, i)) < si%radius + sj%radius
      else if (si%kind == SHAPE_SPHERE) then
        call sphere_mesh_distance(bodies%x(:, i), si%radius, sj%tree, bodies%x(:, j), bodies%q(:, j), d)
        overlap = d%distance <= 0.0_dp
        if (.not. overlap) overlap = winding_number(sj%tree, quat_rotate_inverse(bodies%q(:, j), &
                                                                                  bodies%x(:, i) - bodies%x(:, j))) > 0.5_dp
      else if (sj%kind == SHAPE_SPHERE) then
        call sphere_mesh_distance(bodies%x(:, j), sj%radius, si%tree, bodies%x(:, i), bodies%q(:, i), d)
        overlap = d%distance <= 0.0_dp
        if (.not. overlap) overlap = winding_number(si%tree, quat_rotate_inverse(bodies%q(:, i), &
                                                                                  bodies%x(:, j) - bodies%x(:, i))) > 0.5_dp
      else
        overlap = bodies_overlap(si%tree, bodies%x(:, i), bodies%q(:, i), sj%tree, bodies%x(:, j), bodies%q(:, j))
      end if
    end associate
  end function pair_overlaps

end module overlap_check
