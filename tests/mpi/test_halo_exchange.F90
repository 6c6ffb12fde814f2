! ctest-ranks: 4
!> halo_exchange over the ranks this runs on (4: dims 4x1x1, 1x4x1, 1x1x4, 2x2x1, 2x1x2,
!> 1x2x2; 2: 2x1x1, 1x2x1, 1x1x2; test_halo_exchange_2ranks includes this file). Every rank
!> builds the same reproducible scene: a few hundred bodies with a distinct value in every
!> field, some exactly on brick faces, edges and corners of that decomposition, some on box
!> faces and on the scene's bounds, a few outside them (they clamp to the edge bricks),
!> gids shuffled against the rows. A rank keeps the bodies it owns (owner_of), starts with
!> stale ghosts, and exchanges with rings 1 then 2: its ghosts must be exactly the bodies
!> of the full list whose centre lies in halo_region(rings) but not in its brick (a brute
!> force over the list, agreeing with in_halo), in increasing gid (so each once), each row
!> bit for bit the owner's, versions carried; owned rows untouched; the counts of bodies
!> and bytes consistent over the ranks (sent = received) and with the buffer layout.
!> Then without versions, and the failures: misuse every rank sees (rings 3, another rank
!> grid, a domain of another rank) returns an error on every rank, and a NaN position on
!> one rank fails that rank only, with nobody left waiting.
program test_halo_exchange
  use kinds, only: dp, i8
  use error_status, only: error_t
  use parallel_env, only: parallel_t
  use domain, only: domain_t, box_range_t
  use body_state, only: bodies_t
  use body_packing, only: PACK_HEADER_WORDS, BODY_WORDS
  use halo_exchange, only: exchange_halo, halo_stats_t
  use random_stream, only: random_stream_t
  use string_utils, only: str
  use body_fixtures, only: filled_bodies, same_row
  use assertions
  implicit none

  real(dp), parameter :: H = 0.25_dp
  ! grid boxes x 0..12 (13), y 0..10 (11), z 0..8 (9): every axis splits over 4 ranks
  real(dp), parameter :: LOWER(3) = [0.0_dp, 0.0_dp, 0.0_dp], UPPER(3) = [3.0_dp, 2.5_dp, 2.0_dp]
  integer, parameter :: N_RANDOM = 300, N_SPECIAL = 150
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
      call one_decomposition(CASES_4(:, c), 10 + c)
    end do
  case (2)
    do c = 1, size(CASES_2, 2)
      call one_decomposition(CASES_2(:, c), 20 + c)
    end do
  case default
    call check(par%n_ranks == 1, 'runs on 1, 2 or 4 ranks')
    if (par%n_ranks == 1) call one_decomposition(CASES_1(:, 1), 31)
  end select
  call misuse()
  call failure_on_one_rank()
  call par%free()
  call test_finish()

contains

  !> The scene of one decomposition (the same on every rank), then the exchanges.
  subroutine one_decomposition(dims, seed)
    integer, intent(in) :: dims(3)
    integer, intent(in) :: seed
    type(error_t) :: err
    type(domain_t) :: dom
    type(bodies_t) :: full, local
    integer(i8), allocatable :: versions(:), my_versions(:)
    integer, allocatable :: mine(:)
    integer :: rings, k
    call par%cart_create(dims, err)
    call check(err%ok(), 'cart_create '//dims_text(dims))
    call check(par%cart_rank == par%rank, dims_text(dims)//': the Cartesian rank is the world rank')
    call dom%init(H, LOWER, UPPER, dims, par%cart_rank, err)
    call check(err%ok(), dims_text(dims)//': domain init')
    if (err%failed()) return
    call make_scene(dom, seed, full, versions)
    mine = pack([(k, k=1, full%n_total())], [(dom%owner_of(full%x(:, k)) == dom%rank, k=1, full%n_total())])
    call check(par%sum(size(mine)) == full%n_total(), dims_text(dims)//': every body has one owner')
    call local%append_rows(full, mine, .false.)
    my_versions = versions(mine)
    ! stale ghosts from "an earlier exchange": they must go
    call local%append_rows(full, [1, 2, 3], .true.)
    do rings = 1, 2
      call exchange_and_check(dom, full, versions, local, my_versions, rings, .true.)
    end do
    call exchange_and_check(dom, full, versions, local, my_versions, 1, .false.)
    call payload_check(dom, full, local, my_versions)
  end subroutine one_decomposition

  !> The caller's payload (what cross-rank windows send: the owner's rank and the flight
  !> record) travels with every ghost bit for bit, next to its version: payload(:, k) of
  !> owned row k is [gid * 7 + 3, the bits of x(3), rank], made again here from the full list.
  subroutine payload_check(dom, full, local, my_versions)
    type(domain_t), intent(in) :: dom
    type(bodies_t), intent(in) :: full
    type(bodies_t), intent(inout) :: local
    integer(i8), intent(in) :: my_versions(:)
    type(error_t) :: err
    integer(i8), allocatable :: payload(:, :), ghost_payload(:, :), ghost_versions(:)
    integer :: k, row, bad, owner
    character(len=:), allocatable :: what
    what = dims_text(dom%dims)//' rings 2 payload rank '//str(dom%rank)
    allocate (payload(3, local%n_owned))
    do k = 1, local%n_owned
      payload(:, k) = [local%gid(k)*7_i8 + 3_i8, transfer(local%x(3, k), 1_i8), int(par%rank, i8)]
    end do
    call exchange_halo(par, dom, local, 2, err, my_versions, ghost_versions, payload=payload, &
                       ghost_payload=ghost_payload)
    call check(err%ok() .and. .not. par%any(err%failed()), what//': exchange succeeds')
    call check(size(ghost_payload, 1) == 3 .and. size(ghost_payload, 2) == local%n_ghost, &
               what//': a payload column per ghost')
    if (size(ghost_payload, 2) /= local%n_ghost) return
    bad = 0
    do k = 1, local%n_ghost
      row = row_of_gid(full, local%gid(local%n_owned + k))
      owner = dom%owner_of(full%x(:, row))
      if (any(ghost_payload(:, k) /= [full%gid(row)*7_i8 + 3_i8, transfer(full%x(3, row), 1_i8), &
                                      int(owner, i8)])) bad = bad + 1
    end do
    call check(bad == 0, what//': payload carried bit for bit with its ghost ('//str(bad)//' wrong)')
    ! payload without ghost_payload: an error on every rank, before any message
    call exchange_halo(par, dom, local, 2, err, payload=payload)
    call check(err%failed(), what//': payload alone is refused')
  end subroutine payload_check

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
    ! brick faces along each axis: every brick's lower face (the scene's lower bound for
    ! the first), the scene's upper bound and the face above the last box (outside)
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
    allocate (points(3, N_RANDOM + N_SPECIAL + product(n_faces)))
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
        case (0:2)      ! a brick face (or bound)
          points(d, n) = faces(1 + int(n_faces(d)*rng%uniform()), d)
        case (3)        ! a box face
          points(d, n) = real(dom%global%lo(d) + int(real(dom%n_boxes(d), dp)*rng%uniform(), i8), dp)*H
        case default
          points(d, n) = LOWER(d) + (UPPER(d) - LOWER(d))*rng%uniform()
        end select
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
    ! the scene does what it says: bodies exactly on inner brick faces, and on corners
    i = 0
    j = 0
    do k = 1, n
      l = count([(on_inner_face(dom, d, points(d, k)), d=1, 3)])
      if (l >= 1) i = i + 1
      if (l == count(dom%dims > 1)) j = j + 1
    end do
    call check((i >= 20 .and. j >= 4) .or. product(dom%dims) == 1, dims_text(dom%dims)//': '//str(i)// &
               ' bodies on inner brick faces, '//str(j)//' on inner edges or corners')
  end subroutine make_scene

  !> Whether coordinate x along axis d is exactly on a face between two bricks.
  logical function on_inner_face(dom, d, x)
    type(domain_t), intent(in) :: dom
    integer, intent(in) :: d
    real(dp), intent(in) :: x
    type(box_range_t) :: b
    integer :: c
    on_inner_face = .false.
    do c = 1, dom%dims(d) - 1
      b = dom%brick(dom%rank_of(merge(c, 0, [1, 2, 3] == d)))
      if (x == real(b%lo(d), dp)*H) on_inner_face = .true.
    end do
  end function on_inner_face

  !> One exchange of `rings` rings and everything it must give.
  subroutine exchange_and_check(dom, full, versions, local, my_versions, rings, with_versions)
    type(domain_t), intent(in) :: dom
    type(bodies_t), intent(in) :: full
    integer(i8), intent(in) :: versions(:)
    type(bodies_t), intent(inout) :: local
    integer(i8), intent(in) :: my_versions(:)
    integer, intent(in) :: rings
    logical, intent(in) :: with_versions
    type(error_t) :: err
    type(bodies_t) :: before
    type(halo_stats_t) :: stats
    type(box_range_t) :: region
    integer(i8), allocatable :: ghost_versions(:), expected(:)
    integer, allocatable :: expected_rows(:)
    integer :: k, n0, row, bad_rows, bad_versions, n_faces, d
    integer(i8) :: sent, received
    character(len=:), allocatable :: what
    logical :: ok, in_halo_agrees
    what = dims_text(dom%dims)//' rings '//str(rings)//merge(' versions   ', ' no versions', with_versions)// &
           ' rank '//str(dom%rank)
    n0 = local%n_owned
    call before%append_rows(local, [(k, k=1, n0)], .false.)
    if (with_versions) then
      call exchange_halo(par, dom, local, rings, err, my_versions, ghost_versions, stats)
    else
      call exchange_halo(par, dom, local, rings, err, ghost_versions=ghost_versions, stats=stats)
    end if
    call check(err%ok(), what//': exchange succeeds')
    if (err%failed()) write (*, '(a)') '  '//err%message
    call check(.not. par%any(err%failed()), what//': no rank failed')

    ! owned rows untouched
    ok = local%n_owned == n0
    do k = 1, min(n0, local%n_owned)
      ok = ok .and. same_row(local, k, before, k)
    end do
    call check(ok, what//': owned rows unchanged')

    ! the brute force: bodies of the full list in the halo region, not owned here
    region = dom%halo_region(rings)
    expected_rows = [integer ::]
    in_halo_agrees = .true.
    do k = 1, full%n_total()
      ok = region%holds(dom%box_of(full%x(:, k))) .and. dom%owner_of(full%x(:, k)) /= dom%rank
      if (ok .neqv. dom%in_halo(full%x(:, k), rings)) in_halo_agrees = .false.
      if (ok) expected_rows = [expected_rows, k]
    end do
    call check(in_halo_agrees, what//': the brute force agrees with in_halo')
    expected = sort_i8(full%gid(expected_rows))
    call check(local%n_ghost == size(expected), what//': '//str(local%n_ghost)//' ghosts, expected '// &
               str(size(expected)))
    ok = .true.
    do k = 2, local%n_ghost
      if (local%gid(n0 + k) <= local%gid(n0 + k - 1)) ok = .false.
    end do
    call check(ok, what//': ghosts in strictly increasing gid (each once)')
    if (local%n_ghost == size(expected)) then
      call check(all(local%gid(n0 + 1:n0 + local%n_ghost) == expected), what//': ghost gids are the halo''s')
    end if
    call check(size(ghost_versions) == local%n_ghost, what//': one version per ghost')

    bad_rows = 0
    bad_versions = 0
    do k = 1, local%n_ghost
      row = row_of_gid(full, local%gid(n0 + k))
      if (row == 0) then
        bad_rows = bad_rows + 1
        cycle
      end if
      if (.not. same_row(local, n0 + k, full, row)) bad_rows = bad_rows + 1
      if (k <= size(ghost_versions)) then
        if (with_versions) then
          if (ghost_versions(k) /= versions(row)) bad_versions = bad_versions + 1
        else
          if (ghost_versions(k) /= 0) bad_versions = bad_versions + 1
        end if
      end if
    end do
    call check(bad_rows == 0, what//': ghost rows bitwise the owner''s ('//str(bad_rows)//' differ)')
    call check(bad_versions == 0, what//': versions carried ('//str(bad_versions)//' wrong)')

    ! the counts: one exchange, a message per face neighbour, the layout's bytes, and over
    ! the ranks everything sent arrived
    n_faces = 0
    do d = 1, 6
      if (dom%face_neighbour(d) >= 0) n_faces = n_faces + 1
    end do
    call check(stats%exchanges == 1 .and. stats%messages_sent == n_faces, what//': a message per face neighbour')
    call check(stats%bytes_sent == 8_i8*(PACK_HEADER_WORDS*stats%messages_sent + &
                                         (BODY_WORDS + merge(1, 0, with_versions))*stats%bodies_sent), &
               what//': bytes sent = headers + records')
    call check(stats%bodies_received == local%n_ghost, what//': every body received is a ghost')
    sent = par%sum(stats%bodies_sent)
    received = par%sum(stats%bodies_received)
    call check(sent == received .and. (sent > 0 .or. par%n_ranks == 1), &
               what//': bodies sent = received over the ranks')
    sent = par%sum(stats%bytes_sent)
    received = par%sum(stats%bytes_received)
    call check(sent == received, what//': bytes sent = received over the ranks')
  end subroutine exchange_and_check

  !> Misuse that every rank sees alike returns an error on every rank before any message;
  !> a domain of another rank (same grid) fails in the passes, on every rank, without
  !> anybody waiting.
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
    call filled_bodies(2, 0, 5, GID0, local)
    local%x(:, 1:2) = 0.5_dp

    call exchange_halo(par, dom, local, 3, err)
    call check_error(err%code, err%message, ['rings must be 1..2'], 'misuse: rings 3')
    call err%clear()
    call exchange_halo(par, dom, local, 0, err)
    call check_error(err%code, err%message, ['rings must be 1..2'], 'misuse: rings 0')
    call err%clear()

    fresh%n_ranks = par%n_ranks     ! never initialised: no Cartesian communicator
    call exchange_halo(fresh, dom, local, 1, err)
    call check_error(err%code, err%message, ['no Cartesian communicator'], 'misuse: no cart_create')
    call err%clear()

    call par%cart_create([1, 1, 1], err)
    call check(err%failed() .eqv. (par%n_ranks > 1), 'misuse: cart_create of a grid of another size fails')
    call err%clear()
    if (par%n_ranks > 1) then
      call par%cart_create([1, par%n_ranks, 1], err)
      call exchange_halo(par, dom, local, 1, err)
      call check_error(err%code, err%message, [character(len=24) :: 'rank grid', 'is not the communicator'], &
                       'misuse: the domain''s grid is not the communicator''s')
      call err%clear()

      ! same grid, the domain of the next rank: every rank fails, nobody waits
      call par%cart_create(dims, err)
      call dom%init(H, LOWER, UPPER, dims, mod(par%cart_rank + 1, par%n_ranks), err)
      call exchange_halo(par, dom, local, 1, err)
      call check_error(err%code, err%message, ['the domain is rank'], 'misuse: a domain of another rank')
      call check(local%n_ghost == 0, 'misuse: no ghosts from a failed exchange')
      call err%clear()
    end if
  end subroutine misuse

  !> A NaN position on rank 0 only: rank 0 fails, the others finish their passes (they
  !> would hang if rank 0 left early) and learn of it through par%any.
  subroutine failure_on_one_rank()
    type(error_t) :: err
    type(domain_t) :: dom
    type(bodies_t) :: local
    integer :: dims(3)
    dims = [1, 1, par%n_ranks]
    call par%cart_create(dims, err)
    call dom%init(H, LOWER, UPPER, dims, par%cart_rank, err)
    call filled_bodies(3, 0, 9, GID0 + 100_i8*par%rank, local)
    local%x(:, 1:3) = reshape([0.5_dp, 0.5_dp, 0.1_dp, 1.0_dp, 1.0_dp, 1.0_dp, 2.0_dp, 2.0_dp, 1.9_dp], [3, 3])
    if (par%rank == 0) local%x(2, 2) = transfer(-2251799813685248_i8, 1.0_dp)   ! a quiet NaN
    call exchange_halo(par, dom, local, 1, err)
    if (par%rank == 0) then
      call check_error(err%code, err%message, ['position is NaN'], 'one rank fails: rank 0 says why')
    else
      call check(err%ok(), 'one rank fails: rank '//str(par%rank)//' finishes its passes')
    end if
    call check(par%any(err%failed()), 'one rank fails: every rank learns of it')
  end subroutine failure_on_one_rank

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

end program test_halo_exchange
