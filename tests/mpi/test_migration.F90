! ctest-ranks: 4
!> migrate_bodies over the ranks this runs on (4: dims 4x1x1, 1x4x1, 1x1x4, 2x2x1, 2x1x2,
!> 1x2x2; 2: 2x1x1, 1x2x1, 1x1x2; test_migration_2ranks includes this file). Every rank
!> builds the same reproducible scene (a few hundred bodies, a distinct value in every
!> field, some on brick faces, edges and corners, a few outside the bounds, gids shuffled
!> against the rows), keeps what it owns, holds stale ghosts, and then every body moves by
!> a random displacement of up to one grid box along each axis, some exactly onto the brick
!> faces, edges and corners of the decomposition. After migrate_bodies: no ghosts, every
!> body owned by exactly one rank (the counts summed over the ranks, and each rank's gids
!> exactly those a brute force over the moved list gives it), rows bit for bit the moved
!> list's, owned rows in strictly increasing gid, versions and payloads carried, new_index right for
!> every row before, and the counts consistent (a message per face neighbour, bytes =
!> headers + records, sent = received, every hop counted: forwarding along x, y, z).
!> A second migration without motion moves nothing. Then the failures: a body moved two
!> bricks (4 ranks, 4x1x1) and a NaN position fail on the holder only, naming the body,
!> every rank returns and every other body still migrates; misuse fails everywhere.
program test_migration
  use kinds, only: dp, i8
  use error_status, only: error_t
  use parallel_env, only: parallel_t
  use domain, only: domain_t, box_range_t
  use body_state, only: bodies_t
  use body_packing, only: PACK_HEADER_WORDS, BODY_WORDS
  use migration, only: migrate_bodies, migration_stats_t
  use random_stream, only: random_stream_t
  use string_utils, only: str
  use body_fixtures, only: filled_bodies, same_row
  use assertions
  implicit none

  real(dp), parameter :: H = 0.25_dp
  ! grid boxes x 0..12 (13), y 0..10 (11), z 0..8 (9): every axis splits over 4 ranks
  real(dp), parameter :: LOWER(3) = [0.0_dp, 0.0_dp, 0.0_dp], UPPER(3) = [3.0_dp, 2.5_dp, 2.0_dp]
  integer, parameter :: N_RANDOM = 300, N_SPECIAL = 150, N_CORNER = 80
  integer(i8), parameter :: GID0 = 1000_i8
  integer, parameter :: CASES_4(3, 6) = reshape([4, 1, 1, 1, 4, 1, 1, 1, 4, 2, 2, 1, 2, 1, 2, 1, 2, 2], [3, 6])
  integer, parameter :: CASES_2(3, 3) = reshape([2, 1, 1, 1, 2, 1, 1, 1, 2], [3, 3])
  integer, parameter :: CASES_1(3, 1) = reshape([1, 1, 1], [3, 1])
  type(parallel_t) :: par
  integer :: c

  call par%init()
  select case (par%n_ranks)
  case (4)
    do c = 1, size(CASES_4, 2)
      call one_decomposition(CASES_4(:, c), 40 + c)
    end do
    call moved_two_bricks()
  case (2)
    do c = 1, size(CASES_2, 2)
      call one_decomposition(CASES_2(:, c), 50 + c)
    end do
    ! two bricks away needs three ranks along an axis: every other rank is a neighbour here
  case default
    call check(par%n_ranks == 1, 'runs on 1, 2 or 4 ranks')
    if (par%n_ranks == 1) call one_decomposition(CASES_1(:, 1), 61)
  end select
  call nan_on_one_rank()
  call misuse()
  call par%free()
  call test_finish()

contains

  !> The scene of one decomposition (the same on every rank), its motion, the migration
  !> and everything it must give; then a migration without motion.
  subroutine one_decomposition(dims, seed)
    integer, intent(in) :: dims(3)
    integer, intent(in) :: seed
    type(error_t) :: err
    type(domain_t) :: dom
    type(bodies_t) :: full, moved, local, before
    type(migration_stats_t) :: stats
    integer(i8), allocatable :: versions(:), my_versions(:), expected(:), payload(:, :)
    integer, allocatable :: payload_rows(:)
    logical :: leavers_only
    integer :: m
    integer, allocatable :: mine(:), new_index(:), expected_rows(:)
    integer :: k, row, n_before, n_owned_before, n_changed, n_hops, n_diagonal, bad_rows, bad_versions, bad_payload, bad_index, n_faces, d
    integer :: old_c(3), new_c(3)
    integer(i8) :: sent, received
    character(len=:), allocatable :: what
    logical :: ok
    what = dims_text(dims)//' rank '//str(par%rank)
    call par%cart_create(dims, err)
    call check(err%ok(), 'cart_create '//dims_text(dims))
    call dom%init(H, LOWER, UPPER, dims, par%cart_rank, err)
    call check(err%ok(), what//': domain init')
    if (err%failed()) return
    call make_scene(dom, seed, full, versions)
    call displace(dom, full, seed + 1000, moved)

    ! the motion does what it says (computed alike on every rank): bodies change owner,
    ! some to edge and corner neighbours (forwarded), none by more than one brick
    n_changed = 0
    n_hops = 0
    n_diagonal = 0
    ok = .true.
    do k = 1, full%n_total()
      old_c = dom%coords_of(dom%owner_of(full%x(:, k)))
      new_c = dom%coords_of(dom%owner_of(moved%x(:, k)))
      if (any(old_c /= new_c)) n_changed = n_changed + 1
      n_hops = n_hops + count(old_c /= new_c)
      if (count(old_c /= new_c) >= 2) n_diagonal = n_diagonal + 1
      if (any(abs(old_c - new_c) > 1)) ok = .false.
    end do
    call check(ok, what//': no body moves more than one brick')
    call check(n_changed >= 20 .or. product(dims) == 1, what//': '//str(n_changed)//' bodies change owner')
    call check(n_diagonal >= 4 .or. count(dims > 1) < 2, what//': '//str(n_diagonal)// &
               ' bodies go to an edge or corner neighbour')

    mine = pack([(k, k=1, full%n_total())], [(dom%owner_of(full%x(:, k)) == dom%rank, k=1, full%n_total())])
    call check(par%sum(size(mine)) == full%n_total(), what//': every body has one owner before')
    ! the owned rows as they are at the window end: the old owner's, at the new positions
    call local%append_rows(moved, mine, .false.)
    my_versions = versions(mine)
    call local%append_rows(moved, [1, 2, 3], .true.)    ! stale ghosts: they must go
    n_before = local%n_total()
    n_owned_before = local%n_owned
    call before%append_rows(local, [(k, k=1, n_owned_before)], .false.)

    ! a payload of three words a body (as the flight records travel): made from the version
    ! and gid, so that each body's words are its own; every other seed, only the bodies
    ! that leave carry one (payload_rows: as a window's start sends the flight records)
    leavers_only = mod(seed, 2) == 0
    if (leavers_only) then
      payload_rows = pack([(k, k=1, n_owned_before)], &
                          [(dom%owner_of(local%x(:, k)) /= dom%rank, k=1, n_owned_before)])
    else
      payload_rows = [(k, k=1, n_owned_before)]
    end if
    allocate (payload(3, size(payload_rows)))
    do k = 1, size(payload_rows)
      row = payload_rows(k)
      payload(:, k) = [ieor(my_versions(row), 12345_i8), local%gid(row), not(my_versions(row))]
    end do
    call migrate_bodies(par, dom, local, err, my_versions, new_index, stats, payload=payload, &
                        payload_rows=payload_rows)
    call check(err%ok(), what//': migration succeeds')
    if (err%failed()) write (*, '(a)') '  '//err%message
    call check(.not. par%any(err%failed()), what//': no rank failed')
    call check(local%n_ghost == 0, what//': no ghosts after')

    ! the brute force: bodies of the moved list whose owner is this rank
    expected_rows = pack([(k, k=1, moved%n_total())], &
                         [(dom%owner_of(moved%x(:, k)) == dom%rank, k=1, moved%n_total())])
    expected = sort_i8(moved%gid(expected_rows))
    call check(par%sum(local%n_owned) == moved%n_total(), what//': '//str(par%sum(local%n_owned))// &
               ' owned over the ranks, '//str(moved%n_total())//' bodies')
    call check(local%n_owned == size(expected), what//': '//str(local%n_owned)//' owned, expected '// &
               str(size(expected)))
    if (local%n_owned == size(expected)) then
      call check(all(local%gid(1:local%n_owned) == expected), what//': owned gids are the brute force''s')
    end if
    ok = .true.
    do k = 2, local%n_owned
      if (local%gid(k) <= local%gid(k - 1)) ok = .false.
    end do
    call check(ok, what//': owned rows in strictly increasing gid')

    bad_rows = 0
    bad_versions = 0
    bad_payload = 0
    call check(size(my_versions) == local%n_owned, what//': one version per owned row')
    do k = 1, local%n_owned
      row = row_of_gid(moved, local%gid(k))
      if (row == 0) then
        bad_rows = bad_rows + 1
        cycle
      end if
      if (.not. same_row(local, k, moved, row)) bad_rows = bad_rows + 1
      if (k <= size(my_versions)) then
        if (my_versions(k) /= versions(row)) bad_versions = bad_versions + 1
      end if
    end do
    ! (exactly the rows that arrived carry one, or every row)
    if (leavers_only) then
      call check(all(payload_rows == pack([(k, k=1, local%n_owned)], [(.not. any(new_index == k), k=1, local%n_owned)])), &
                 what//': the payload rows are those that arrived')
    else
      call check(size(payload_rows) == local%n_owned .and. all(payload_rows == [(k, k=1, local%n_owned)]), &
                 what//': every owned row carries its payload')
    end if
    do m = 1, min(size(payload_rows), size(payload, 2))
      k = payload_rows(m)
      row = row_of_gid(moved, local%gid(k))
      if (row == 0) cycle
      if (any(payload(:, m) /= [ieor(versions(row), 12345_i8), local%gid(k), not(versions(row))])) &
        bad_payload = bad_payload + 1
    end do
    call check(size(payload, 1) == 3 .and. size(payload, 2) == size(payload_rows), what//': one payload per row '// &
               merge('that arrived', 'owned       ', leavers_only))
    call check(bad_payload == 0, what//': payloads carried, bit for bit ('//str(bad_payload)//' wrong)')
    call check(bad_rows == 0, what//': rows bitwise the moved list''s ('//str(bad_rows)//' differ)')
    call check(bad_versions == 0, what//': versions carried ('//str(bad_versions)//' wrong)')

    ! new_index: a row that stays names its row after, one that left (or a ghost) is 0
    bad_index = 0
    call check(size(new_index) == n_before, what//': new_index has a row per row before')
    do k = 1, min(n_before, size(new_index))
      ok = .false.       ! stays here (no short-circuit in Fortran: before has owned rows only)
      if (k <= n_owned_before) ok = dom%owner_of(before%x(:, k)) == dom%rank
      if (ok) then
        if (new_index(k) < 1 .or. new_index(k) > local%n_owned) then
          bad_index = bad_index + 1
        else if (local%gid(new_index(k)) /= before%gid(k)) then
          bad_index = bad_index + 1
        end if
      else if (new_index(k) /= 0) then
        bad_index = bad_index + 1
      end if
    end do
    call check(bad_index == 0, what//': new_index right ('//str(bad_index)//' wrong)')

    ! the counts
    n_faces = 0
    do d = 1, 6
      if (dom%face_neighbour(d) >= 0) n_faces = n_faces + 1
    end do
    call check(stats%migrations == 1 .and. stats%messages_sent == n_faces, what//': a message per face neighbour')
    call check(stats%bytes_sent == 8_i8*(PACK_HEADER_WORDS*stats%messages_sent + (BODY_WORDS + 1 + 3)*stats%bodies_sent), &
               what//': bytes sent = headers + records')
    call check(stats%bodies_left == count([(dom%owner_of(before%x(:, k)) /= dom%rank, k=1, before%n_owned)]), &
               what//': bodies left = owned bodies now elsewhere')
    call check(stats%bodies_arrived == local%n_owned - count(new_index > 0), what//': bodies arrived')
    sent = par%sum(stats%bodies_sent)
    received = par%sum(stats%bodies_received)
    call check(sent == received .and. sent == n_hops, what//': bodies sent '//str(sent)//' = received '// &
               str(received)//' = hops '//str(n_hops)//' (forwarded ones at each)')
    call check(par%sum(stats%bodies_left) == n_changed .and. par%sum(stats%bodies_arrived) == n_changed, &
               what//': bodies left = arrived = changed owner over the ranks')
    sent = par%sum(stats%bytes_sent)
    received = par%sum(stats%bytes_received)
    call check(sent == received, what//': bytes sent = received over the ranks')

    ! at rest: nothing moves, rows untouched, without the optional arguments
    call before%free()
    call before%append_rows(local, [(k, k=1, local%n_owned)], .false.)
    stats = migration_stats_t()
    call migrate_bodies(par, dom, local, err, stats=stats)
    call check(err%ok() .and. .not. par%any(err%failed()), what//': at rest: succeeds')
    ok = local%n_owned == before%n_owned
    do k = 1, min(local%n_owned, before%n_owned)
      ok = ok .and. same_row(local, k, before, k)
    end do
    call check(ok, what//': at rest: rows unchanged')
    call check(stats%bodies_sent == 0 .and. stats%bodies_left == 0 .and. stats%bodies_arrived == 0, &
               what//': at rest: nothing sent')
  end subroutine one_decomposition

  !> Random bodies in and a little around the scene's bounds, then bodies on this
  !> decomposition's brick faces (each axis: a brick face, a box face or anywhere), every
  !> brick corner; every field distinct (filled_bodies), gids a shuffle of GID0 + 7 k.
  subroutine make_scene(dom, seed, full, versions)
    type(domain_t), intent(in) :: dom
    integer, intent(in) :: seed
    type(bodies_t), intent(inout) :: full
    integer(i8), allocatable, intent(out) :: versions(:)
    type(random_stream_t) :: rng
    real(dp), allocatable :: points(:, :)
    real(dp), allocatable :: faces(:, :)   ! (face, axis): coordinates of brick faces
    integer :: n_faces(3), n, d, k, i, j, l, c, tmp
    integer, allocatable :: perm(:)
    type(box_range_t) :: b
    call rng%init(seed)
    allocate (faces(maxval(dom%dims) + 2, 3))
    do d = 1, 3
      n_faces(d) = 0
      do c = 0, dom%dims(d) - 1
        b = dom%brick(dom%rank_of(merge(c, 0, [1, 2, 3] == d)))
        n_faces(d) = n_faces(d) + 1
        faces(n_faces(d), d) = real(b%lo(d), dp)*H
      end do
      faces(n_faces(d) + 1, d) = UPPER(d)
      faces(n_faces(d) + 2, d) = real(dom%global%hi(d) + 1, dp)*H
      n_faces(d) = n_faces(d) + 2
    end do
    allocate (points(3, N_RANDOM + N_SPECIAL + N_CORNER + product(n_faces)))
    n = 0
    do k = 1, N_RANDOM
      n = n + 1
      do d = 1, 3
        points(d, n) = LOWER(d) - 0.1_dp + (UPPER(d) - LOWER(d) + 0.2_dp)*rng%uniform()
      end do
    end do
    do k = 1, N_SPECIAL
      n = n + 1
      do d = 1, 3
        select case (int(5*rng%uniform()))
        case (0:2)
          points(d, n) = faces(1 + int(n_faces(d)*rng%uniform()), d)
        case (3)
          points(d, n) = real(dom%global%lo(d) + int(real(dom%n_boxes(d), dp)*rng%uniform(), i8), dp)*H
        case default
          points(d, n) = LOWER(d) + (UPPER(d) - LOWER(d))*rng%uniform()
        end select
      end do
    end do
    ! within half a box of an inner brick edge or corner: the motion sends many of them to
    ! an edge or corner neighbour (forwarded) or exactly onto the edge
    do k = 1, N_CORNER
      n = n + 1
      do d = 1, 3
        if (dom%dims(d) > 1) then
          c = 1 + int((dom%dims(d) - 1)*rng%uniform())
          b = dom%brick(dom%rank_of(merge(c, 0, [1, 2, 3] == d)))
          points(d, n) = real(b%lo(d), dp)*H + rng%symmetric(0.5_dp*H)
        else
          points(d, n) = LOWER(d) + (UPPER(d) - LOWER(d))*rng%uniform()
        end if
      end do
    end do
    do i = 1, n_faces(1)
      do j = 1, n_faces(2)
        do l = 1, n_faces(3)
          n = n + 1
          points(:, n) = [faces(i, 1), faces(j, 2), faces(l, 3)]
        end do
      end do
    end do
    call filled_bodies(n, 0, seed, GID0, full)
    full%x(:, 1:n) = points(:, 1:n)
    perm = [(k, k=1, n)]
    do k = n, 2, -1            ! Fisher-Yates
      i = 1 + int(k*rng%uniform())
      tmp = perm(k); perm(k) = perm(i); perm(i) = tmp
    end do
    full%gid(1:n) = GID0 + 7_i8*perm
    allocate (versions(n))
    do k = 1, n
      versions(k) = rng%next_u64()      ! any 64 bits: negative and NaN patterns too
    end do
  end subroutine make_scene

  !> The full list after a window: every body moved by up to one grid box along each axis;
  !> along an axis, half the bodies within a box of an inner brick face land exactly
  !> on it (several axes: an edge or a corner). Checks that the scene has such bodies.
  subroutine displace(dom, full, seed, moved)
    type(domain_t), intent(in) :: dom
    type(bodies_t), intent(in) :: full
    integer, intent(in) :: seed
    type(bodies_t), intent(inout) :: moved
    type(random_stream_t) :: rng
    type(box_range_t) :: b
    real(dp) :: face, x_old
    integer :: k, d, c, on_faces, n_face, n_edge
    call rng%init(seed)
    call moved%free()
    call moved%append_rows(full, [(k, k=1, full%n_total())], .false.)
    n_face = 0
    n_edge = 0
    do k = 1, moved%n_owned
      on_faces = 0
      do d = 1, 3
        x_old = full%x(d, k)
        moved%x(d, k) = x_old + rng%symmetric(H)
        do c = 1, dom%dims(d) - 1
          b = dom%brick(dom%rank_of(merge(c, 0, [1, 2, 3] == d)))
          face = real(b%lo(d), dp)*H
          if (abs(face - x_old) <= H .and. rng%uniform() < 0.5_dp) moved%x(d, k) = face
          if (moved%x(d, k) == face) on_faces = on_faces + 1
        end do
      end do
      if (on_faces >= 1) n_face = n_face + 1
      if (on_faces >= 2 .or. (on_faces == 1 .and. count(dom%dims > 1) == 1)) n_edge = n_edge + 1
    end do
    call check((n_face >= 20 .and. n_edge >= 4) .or. product(dom%dims) == 1, dims_text(dom%dims)//': '// &
               str(n_face)//' bodies moved onto inner brick faces, '//str(n_edge)//' onto edges or corners')
  end subroutine displace

  !> 4x1x1: a body of rank 0 moved into rank 2's brick (two bricks away) fails on rank 0,
  !> naming it, its position and both ranks; it stays there, while a body of rank 1 moving
  !> to rank 2 and one of rank 3 moving to rank 2 still arrive, and every rank returns.
  subroutine moved_two_bricks()
    type(error_t) :: err
    type(domain_t) :: dom
    type(bodies_t) :: local
    integer(i8), allocatable :: versions(:)
    integer, allocatable :: new_index(:)
    integer :: dims(3)
    real(dp), parameter :: START_X(0:3) = [0.3_dp, 1.0_dp, 1.8_dp, 2.6_dp]   ! bricks x 0..2, 3..5, 6..8, 9..12 boxes
    integer(i8) :: far_gid
    character(len=40) :: fragments(5)
    dims = [4, 1, 1]
    call par%cart_create(dims, err)
    call dom%init(H, LOWER, UPPER, dims, par%cart_rank, err)
    call check(err%ok() .and. dom%owner_of([START_X(par%rank), 1.0_dp, 1.0_dp]) == par%rank, &
               'two bricks: setup')
    ! rank r holds gids 10 r + 1 .. 10 r + 3, at its brick's middle
    call filled_bodies(3, 0, 70 + par%rank, GID0, local)
    local%gid(1:3) = 10_i8*par%rank + [1_i8, 2_i8, 3_i8]
    local%x(1, 1:3) = START_X(par%rank)
    local%x(2:3, 1:3) = 1.0_dp
    far_gid = 2_i8
    if (par%rank == 0) local%x(1, 2) = 1.625_dp                 ! box 6: rank 2, two bricks away
    if (par%rank == 1) local%x(1, 3) = 1.5_dp                   ! exactly on rank 2's lower face
    if (par%rank == 3) local%x(1, 1) = 2.0_dp                   ! rank 2's brick, from above
    versions = 100_i8*par%rank + [1_i8, 2_i8, 3_i8]
    call migrate_bodies(par, dom, local, err, versions, new_index)
    if (par%rank == 0) then
      if (err%failed()) then
        ! fragments built one by one: a constructor of non-constant strings with a type-spec
        ! writes past its buffer in gfortran 12
        fragments(1) = 'body '//str(far_gid)//' at ('
        fragments(2) = '1.625'
        fragments(3) = 'belongs to rank 2'
        fragments(4) = 'rank 0 holding it'
        fragments(5) = 'more than one brick'
        call check_error(err%code, err%message, fragments, 'two bricks: rank 0 names the body')
      else
        call check(.false., 'two bricks: rank 0 fails')
      end if
      call check(any(local%gid(1:local%n_owned) == far_gid), 'two bricks: the body stays on rank 0')
      call check(all(new_index == [1, 2, 3]), 'two bricks: rank 0 keeps its rows')
    else
      call check(err%ok(), 'two bricks: rank '//str(par%rank)//' finishes its passes without error')
    end if
    call check(par%any(err%failed()), 'two bricks: every rank learns of it')
    call check(par%sum(local%n_owned) == 12, 'two bricks: every body still held once')
    if (par%rank == 2) then
      call check(local%n_owned == 5 .and. all(local%gid(1:5) == [13_i8, 21_i8, 22_i8, 23_i8, 31_i8]), &
                 'two bricks: the other movers arrive at rank 2, in gid order')
      call check(all(versions == [103_i8, 201_i8, 202_i8, 203_i8, 301_i8]), 'two bricks: their versions too')
    end if
  end subroutine moved_two_bricks

  !> A NaN position on rank 0 only (dims 1x1xn): rank 0 fails naming the body, which it
  !> keeps, its other body bound for rank 1 still goes, the others finish their passes
  !> (they would hang if rank 0 left early) and learn of it through par%any.
  subroutine nan_on_one_rank()
    type(error_t) :: err
    type(domain_t) :: dom
    type(bodies_t) :: local
    type(box_range_t) :: next
    character(len=40) :: fragments(2)
    integer :: dims(3)
    dims = [1, 1, par%n_ranks]
    call par%cart_create(dims, err)
    call dom%init(H, LOWER, UPPER, dims, par%cart_rank, err)
    call filled_bodies(3, 0, 9, GID0 + 100_i8*par%rank, local)
    ! a body of each rank's at z = 0.1 (rank 0's brick), one at 1.0, one at 1.9 (the last)
    local%x(:, 1:3) = reshape([0.5_dp, 0.5_dp, 0.1_dp, 1.0_dp, 1.0_dp, 1.0_dp, 2.0_dp, 2.0_dp, 1.9_dp], [3, 3])
    if (par%rank == 0) local%x(2, 2) = transfer(-2251799813685248_i8, 1.0_dp)   ! a quiet NaN
    ! only the NaN is an error: rank 0's last body goes one brick up, the others stay
    if (par%n_ranks > 1) then
      next = dom%brick(1)
      if (par%rank == 0) local%x(3, 3) = real(next%lo(3), dp)*H                 ! rank 1's lower face
      if (par%rank > 0) local%x(3, :) = (real(dom%own%lo(3), dp) + 0.5_dp)*H    ! its own brick
    end if
    call migrate_bodies(par, dom, local, err)
    if (par%rank == 0) then
      if (err%failed()) then
        fragments(1) = 'body '//str(GID0 + 14_i8)//' at ('
        fragments(2) = 'NaN position'
        call check_error(err%code, err%message, fragments, 'NaN: rank 0 names the body')
      else
        call check(.false., 'NaN: rank 0 fails')
      end if
      call check(any(local%gid(1:local%n_owned) == GID0 + 14_i8), 'NaN: the body stays on rank 0')
      call check(all(local%gid(1:local%n_owned) /= GID0 + 21_i8) .eqv. (par%n_ranks > 1), &
                 'NaN: rank 0''s other mover still left')
    else
      call check(err%ok(), 'NaN: rank '//str(par%rank)//' finishes its passes')
    end if
    call check(par%any(err%failed()), 'NaN: every rank learns of it')
    call check(par%sum(local%n_owned) == 3*par%n_ranks, 'NaN: every body still held once')
  end subroutine nan_on_one_rank

  !> Misuse every rank sees alike fails on every rank before any message, rows unchanged.
  subroutine misuse()
    type(error_t) :: err
    type(domain_t) :: dom
    type(bodies_t) :: local
    type(parallel_t) :: fresh
    integer :: dims(3)
    dims = [par%n_ranks, 1, 1]
    call par%cart_create(dims, err)
    call dom%init(H, LOWER, UPPER, dims, par%cart_rank, err)
    call check(err%ok(), 'misuse: setup')
    call filled_bodies(2, 1, 5, GID0, local)
    local%x(:, 1:3) = 0.5_dp
    fresh%n_ranks = par%n_ranks     ! never initialised: no Cartesian communicator
    call migrate_bodies(fresh, dom, local, err)
    call check_error(err%code, err%message, ['no Cartesian communicator'], 'misuse: no cart_create')
    call check(local%n_owned == 2 .and. local%n_ghost == 1, 'misuse: rows unchanged')
    call err%clear()
    if (par%n_ranks > 1) then
      call par%cart_create([1, par%n_ranks, 1], err)
      call migrate_bodies(par, dom, local, err)
      call check_error(err%code, err%message, [character(len=24) :: 'rank grid', 'is not the communicator'], &
                       'misuse: the domain''s grid is not the communicator''s')
      call err%clear()
    end if
  end subroutine misuse

  integer function row_of_gid(b, gid)
    type(bodies_t), intent(in) :: b
    integer(i8), intent(in) :: gid
    integer :: k
    row_of_gid = 0
    do k = 1, b%n_total()
      if (b%gid(k) == gid) then
        row_of_gid = k
        return
      end if
    end do
  end function row_of_gid

  function sort_i8(values) result(sorted)
    integer(i8), intent(in) :: values(:)
    integer(i8) :: sorted(size(values)), t
    integer :: i, j
    sorted = values
    do i = 2, size(sorted)      ! insertion sort: a few hundred values
      t = sorted(i)
      j = i - 1
      do while (j >= 1)
        if (sorted(j) <= t) exit
        sorted(j + 1) = sorted(j)
        j = j - 1
      end do
      sorted(j + 1) = t
    end do
  end function sort_i8

  function dims_text(dims) result(text)
    integer, intent(in) :: dims(3)
    character(len=:), allocatable :: text
    text = str(dims(1))//'x'//str(dims(2))//'x'//str(dims(3))
  end function dims_text

end program test_migration
