!> domain: bricks of whole grid boxes over 1x1x1 .. 3x3x1 ranks, all ranks simulated in one
!> process. Every box is in exactly one brick (balanced, >= 2 boxes per split axis);
!> owner_of inside, exactly on brick faces, edges and corners (the upper brick), just
!> below them, and outside the global box (edge bricks; NaN: no rank); ranks and
!> coordinates in MPI_Cart_create's row-major order. The staged exchange (x, y, z passes,
!> each rank sending halo_send_boxes to its face neighbours, forwarding what it received)
!> gives every rank exactly its one- or two-ring halo, each box once, in at most 6
!> messages; in_halo and neighbours agree with it. Then the dims suggestion (as
!> MPI_Dims_create) and the input errors. The box edge is 0.25 m, a power of two, so brick
!> faces k*h are exact doubles and "exactly on a face" means what it says; everything is
!> integer or exact, compared exactly.
program test_domain
  use kinds, only: dp, i8
  use error_status, only: error_t
  use domain, only: domain_t, box_range_t, suggest_dims, NO_RANK, MINUS_X, PLUS_Z
  use assertions
  implicit none

  real(dp), parameter :: H = 0.25_dp
  ! the scene: x boxes -5..12 (18), y 1..10 (10), z 0..7 (8)
  real(dp), parameter :: LOWER(3) = [-1.1_dp, 0.3_dp, 0.0_dp], UPPER(3) = [3.2_dp, 2.6_dp, 1.9_dp]
  integer, parameter :: N_CASES = 7
  integer, parameter :: CASES(3, N_CASES) = reshape([1, 1, 1, 2, 1, 1, 2, 2, 1, 3, 1, 1, 2, 2, 2, 3, 3, 1, &
                                                     1, 2, 3], [3, N_CASES])
  integer :: c, rings

  call global_box()
  do c = 1, N_CASES
    call bricks_partition(CASES(:, c))
    call owners(CASES(:, c))
    do rings = 1, 2
      call staged_exchange(CASES(:, c), rings)
    end do
  end do
  call dims_suggestion()
  call input_errors()
  call test_finish()

contains

  subroutine make(dims, rank, d)
    integer, intent(in) :: dims(3), rank
    type(domain_t), intent(out) :: d
    type(error_t) :: err
    call d%init(H, LOWER, UPPER, dims, rank, err)
    call check(err%ok(), 'init succeeds for dims '//dims_text(dims))
  end subroutine make

  subroutine global_box()
    type(domain_t) :: d
    call make([1, 1, 1], 0, d)
    call check(all(d%global%lo == [-5_i8, 1_i8, 0_i8]) .and. all(d%global%hi == [12_i8, 10_i8, 7_i8]), &
               'global box: the boxes floor(x/h) of the bounds')
    call check(all(d%n_boxes == [18_i8, 10_i8, 8_i8]), 'global box: box counts')
  end subroutine global_box

  !> Every box in exactly one brick, owner_of_box says which; bricks balanced and >= 2 wide;
  !> rank <-> coordinates row-major.
  subroutine bricks_partition(dims)
    integer, intent(in) :: dims(3)
    type(domain_t) :: d
    type(box_range_t) :: b
    integer(i8) :: k(3), kx, ky, kz
    integer :: r, a, n_in, owner, cc(3), lo_w(3), hi_w(3), width
    logical :: ok_once, ok_owner, ok_rank
    call make(dims, 0, d)
    ok_rank = .true.
    lo_w = huge(1)
    hi_w = 0
    do r = 0, d%n_ranks - 1
      cc = d%coords_of(r)
      if ((cc(1)*dims(2) + cc(2))*dims(3) + cc(3) /= r .or. d%rank_of(cc) /= r) ok_rank = .false.
      b = d%brick(r)
      do a = 1, 3
        width = int(b%hi(a) - b%lo(a) + 1)
        lo_w(a) = min(lo_w(a), width)
        hi_w(a) = max(hi_w(a), width)
      end do
    end do
    call check(ok_rank, 'dims '//dims_text(dims)//': rank = (c1*d2 + c2)*d3 + c3 both ways')
    call check(d%rank_of([dims(1), 0, 0]) == NO_RANK .and. d%rank_of([0, -1, 0]) == NO_RANK, &
               'dims '//dims_text(dims)//': outside the rank grid is NO_RANK')
    call check(all(hi_w - lo_w <= 1), 'dims '//dims_text(dims)//': brick widths differ by at most one')
    call check(all(lo_w >= 2 .or. dims == 1), 'dims '//dims_text(dims)//': split axes have >= 2 boxes per rank')
    ok_once = .true.
    ok_owner = .true.
    do kz = d%global%lo(3), d%global%hi(3)
      do ky = d%global%lo(2), d%global%hi(2)
        do kx = d%global%lo(1), d%global%hi(1)
          k = [kx, ky, kz]
          n_in = 0
          owner = NO_RANK
          do r = 0, d%n_ranks - 1
            b = d%brick(r)
            if (b%holds(k)) then
              n_in = n_in + 1
              owner = r
            end if
          end do
          if (n_in /= 1) ok_once = .false.
          if (d%owner_of_box(k) /= owner) ok_owner = .false.
          if (d%owner_of(centre(k)) /= owner) ok_owner = .false.
        end do
      end do
    end do
    call check(ok_once, 'dims '//dims_text(dims)//': every box in exactly one brick')
    call check(ok_owner, 'dims '//dims_text(dims)//': owner_of_box and owner_of(box centre) name that brick')
  end subroutine bricks_partition

  !> Points on brick faces, edges and corners go to the brick above along every axis they
  !> sit on; one ulp below, to the brick below; outside the global box, to the edge bricks.
  subroutine owners(dims)
    integer, intent(in) :: dims(3)
    type(domain_t) :: d
    type(box_range_t) :: b, bb
    real(dp) :: p(3), q(3), far(3)
    integer :: r, mask, a, below(3), n_holding, s
    logical :: ok_on, ok_below, ok_unique
    call make(dims, 0, d)
    ok_on = .true.
    ok_below = .true.
    ok_unique = .true.
    do r = 0, d%n_ranks - 1
      b = d%brick(r)
      ! every combination of the brick's lower faces: 1 face, 2 an edge, 3 a corner
      do mask = 1, 7
        p = centre((b%lo + b%hi)/2)
        q = p
        below = d%coords_of(r)
        do a = 1, 3
          if (btest(mask, a - 1)) then
            p(a) = real(b%lo(a), dp)*H         ! exactly on the face (h is a power of two)
            q(a) = nearest(p(a), -1.0_dp)      ! one ulp below it
            below(a) = below(a) - 1
          end if
        end do
        if (d%owner_of(p) /= r) ok_on = .false.
        ! on the global box's lower faces there is no brick below: one ulp below clamps back
        where (below < 0) below = 0
        if (d%owner_of(q) /= d%rank_of(below)) ok_below = .false.
        n_holding = 0
        do s = 0, d%n_ranks - 1
          bb = d%brick(s)
          if (bb%holds(d%box_of(p))) n_holding = n_holding + 1
        end do
        if (n_holding /= 1) ok_unique = .false.
      end do
    end do
    call check(ok_on, 'dims '//dims_text(dims)//': a point on a brick face, edge or corner belongs to the upper brick')
    call check(ok_below, 'dims '//dims_text(dims)//': one ulp below a face it belongs to the lower brick')
    call check(ok_unique, 'dims '//dims_text(dims)//': a point on a face is in exactly one brick')
    ! outside the global box: clamped to the edge bricks, even for huge and infinite points
    far = [-1.0e300_dp, huge(1.0_dp), -huge(1.0_dp)]
    call check(d%owner_of(far) == d%rank_of([0, dims(2) - 1, 0]), 'dims '//dims_text(dims)// &
               ': far outside: the corner brick')
    call check(d%owner_of([LOWER(1) - 5.0_dp, 1.0_dp, 1.0_dp]) == d%owner_of([LOWER(1), 1.0_dp, 1.0_dp]), &
               'dims '//dims_text(dims)//': below x: the brick at the lower x face')
    p = [ieee_inf(), 1.0_dp, ieee_inf()]
    call check(d%owner_of(p) == d%owner_of_box([d%global%hi(1), 4_i8, d%global%hi(3)]), &
               'dims '//dims_text(dims)//': +Inf clamps to the upper edge')
    p = 0.0_dp
    p(2) = ieee_nan()
    call check(d%owner_of(p) == NO_RANK, 'dims '//dims_text(dims)//': a NaN point has no owner')
  end subroutine owners

  !> All ranks' three-pass exchange, simulated: pass a sends, from what each rank held
  !> before the pass, halo_send_boxes to both face neighbours along a.
  subroutine staged_exchange(dims, rings)
    integer, intent(in) :: dims(3), rings
    type(domain_t), allocatable :: ranks(:)
    logical, allocatable :: have(:, :, :, :), before(:, :, :, :), expected(:, :, :)
    integer, allocatable :: messages(:), duplicates(:)
    type(box_range_t) :: s, b
    integer(i8) :: g_lo(3), g_hi(3), kx, ky, kz, k(3)
    integer :: n, r, a, dir, nb, i, n_faces
    logical :: ok_held, ok_halo, ok_empty, ok_in_halo, ok_neighbours, ok_messages
    integer, allocatable :: halo_owners(:), listed(:)
    character(len=:), allocatable :: what
    what = 'dims '//dims_text(dims)//', '//char(48 + rings)//' ring(s): '
    n = product(dims)
    allocate (ranks(0:n - 1))
    do r = 0, n - 1
      call make(dims, r, ranks(r))
    end do
    g_lo = ranks(0)%global%lo
    g_hi = ranks(0)%global%hi
    allocate (have(g_lo(1):g_hi(1), g_lo(2):g_hi(2), g_lo(3):g_hi(3), 0:n - 1))
    allocate (expected(g_lo(1):g_hi(1), g_lo(2):g_hi(2), g_lo(3):g_hi(3)))
    allocate (messages(0:n - 1), duplicates(0:n - 1))
    have = .false.
    messages = 0
    duplicates = 0
    do r = 0, n - 1
      b = ranks(r)%own
      have(b%lo(1):b%hi(1), b%lo(2):b%hi(2), b%lo(3):b%hi(3), r) = .true.
    end do
    ok_held = .true.
    ok_empty = .true.
    do a = 1, 3
      before = have
      do r = 0, n - 1
        do dir = 2*a - 1, 2*a
          nb = ranks(r)%face_neighbour(dir)
          s = ranks(r)%halo_send_boxes(dir, rings)
          if (nb == NO_RANK) then
            if (.not. s%is_empty()) ok_empty = .false.
            cycle
          end if
          if (s%is_empty()) ok_empty = .false.
          messages(r) = messages(r) + 1
          ! a rank sends only boxes it holds: its brick or what arrived in earlier passes
          if (.not. all(before(s%lo(1):s%hi(1), s%lo(2):s%hi(2), s%lo(3):s%hi(3), r))) ok_held = .false.
          duplicates(nb) = duplicates(nb) + count(have(s%lo(1):s%hi(1), s%lo(2):s%hi(2), s%lo(3):s%hi(3), nb))
          have(s%lo(1):s%hi(1), s%lo(2):s%hi(2), s%lo(3):s%hi(3), nb) = .true.
        end do
      end do
    end do
    call check(ok_held, what//'every rank sends only boxes it holds')
    call check(ok_empty, what//'a message exactly where there is a face neighbour')
    call check(all(duplicates == 0), what//'no box arrives twice')
    ok_halo = .true.
    ok_in_halo = .true.
    ok_neighbours = .true.
    ok_messages = .true.
    do r = 0, n - 1
      ! the two-ring neighbourhood, from its definition: boxes within `rings` of the brick
      ! along every axis (Chebyshev distance), inside the global box
      b = ranks(r)%own
      allocate (halo_owners(0))
      do kz = g_lo(3), g_hi(3)
        do ky = g_lo(2), g_hi(2)
          do kx = g_lo(1), g_hi(1)
            k = [kx, ky, kz]
            expected(kx, ky, kz) = maxval(max(b%lo - k, k - b%hi, 0_i8)) <= rings
            if (ranks(r)%in_halo(centre(k), rings) .neqv. (expected(kx, ky, kz) .and. .not. b%holds(k))) &
              ok_in_halo = .false.
            if (expected(kx, ky, kz) .and. .not. b%holds(k)) then
              i = ranks(r)%owner_of_box(k)
              if (.not. any(halo_owners == i)) halo_owners = [halo_owners, i]
            end if
          end do
        end do
      end do
      if (any(have(:, :, :, r) .neqv. expected)) ok_halo = .false.
      listed = ranks(r)%neighbours()
      if (size(listed) /= size(halo_owners)) then
        ok_neighbours = .false.
      else
        do i = 1, size(listed)
          if (.not. any(halo_owners == listed(i))) ok_neighbours = .false.
        end do
        if (any(listed(2:) <= listed(:size(listed) - 1))) ok_neighbours = .false.
      end if
      n_faces = 0
      do dir = MINUS_X, PLUS_Z
        if (ranks(r)%face_neighbour(dir) /= NO_RANK) n_faces = n_faces + 1
      end do
      if (messages(r) /= n_faces .or. messages(r) > 6) ok_messages = .false.
      deallocate (halo_owners)
    end do
    call check(ok_halo, what//'after 3 passes every rank holds exactly its brick and its halo')
    call check(ok_in_halo, what//'in_halo(box centre) is that halo')
    call check(ok_neighbours, what//'neighbours() are the owners of the halo boxes, ascending')
    call check(ok_messages, what//'one message per face neighbour, at most 6')
  end subroutine staged_exchange

  subroutine dims_suggestion()
    integer, parameter :: NS(7) = [1, 2, 3, 4, 6, 8, 12]
    integer, parameter :: WANT(3, 7) = reshape([1, 1, 1, 2, 1, 1, 3, 1, 1, 2, 2, 1, 3, 2, 1, 2, 2, 2, 3, 2, 2], [3, 7])
    integer :: dims(3), i
    type(error_t) :: err
    do i = 1, size(NS)
      call suggest_dims(NS(i), [0, 0, 0], dims, err)
      call check(err%ok() .and. all(dims == WANT(:, i)), 'suggest_dims('//char(48 + NS(i)/10)//char(48 + mod(NS(i), 10))// &
                 ') = '//dims_text(WANT(:, i))//', got '//dims_text(dims))
    end do
    call suggest_dims(16, [0, 0, 0], dims, err)
    call check(all(dims == [4, 2, 2]), 'suggest_dims(16) = 4 2 2 (as MPI_Dims_create), got '//dims_text(dims))
    call suggest_dims(8, [0, 0, 1], dims, err)
    call check(err%ok() .and. all(dims == [4, 2, 1]), 'suggest_dims(8, 0 0 1) = 4 2 1, got '//dims_text(dims))
    call suggest_dims(12, [2, 0, 0], dims, err)
    call check(err%ok() .and. all(dims == [2, 3, 2]), 'suggest_dims(12, 2 0 0) = 2 3 2, got '//dims_text(dims))
    call suggest_dims(12, [0, 3, 0], dims, err)
    call check(err%ok() .and. all(dims == [2, 3, 2]), 'suggest_dims(12, 0 3 0) = 2 3 2, got '//dims_text(dims))
    call suggest_dims(12, [0, 0, 12], dims, err)
    call check(err%ok() .and. all(dims == [1, 1, 12]), 'suggest_dims(12, 0 0 12) = 1 1 12, got '//dims_text(dims))
    call suggest_dims(12, [2, 3, 2], dims, err)
    call check(err%ok() .and. all(dims == [2, 3, 2]), 'suggest_dims(12, 2 3 2) keeps them')
    ! with box counts the largest factor goes to the longest free axis
    call suggest_dims(6, [0, 0, 0], dims, err, [10_i8, 40_i8, 20_i8])
    call check(err%ok() .and. all(dims == [1, 3, 2]), 'suggest_dims(6) on a scene long in y = 1 3 2, got '// &
               dims_text(dims))
    call suggest_dims(2, [0, 1, 0], dims, err, [8_i8, 100_i8, 8_i8])
    call check(err%ok() .and. all(dims == [2, 1, 1]), 'suggest_dims(2, 0 1 0), equal x and z: x first, got '// &
               dims_text(dims))
    call suggest_dims(6, [4, 0, 0], dims, err)
    call check_error(err%code, err%message, [character(len=16) :: '4 0 0', '6 ranks', 'divide'], &
                     'suggest_dims: fixed entries that do not divide n')
    call err%clear()
    call suggest_dims(12, [2, 3, 1], dims, err)
    call check_error(err%code, err%message, [character(len=16) :: '2 3 1', '12 ranks'], &
                     'suggest_dims: all fixed, wrong product')
    call err%clear()
    call suggest_dims(0, [0, 0, 0], dims, err)
    call check_error(err%code, err%message, [character(len=16) :: '>= 1'], 'suggest_dims: n = 0')
    call err%clear()
    call suggest_dims(4, [0, -2, 0], dims, err)
    call check_error(err%code, err%message, [character(len=16) :: '>= 0', '-2'], 'suggest_dims: negative entry')
  end subroutine dims_suggestion

  subroutine input_errors()
    type(domain_t) :: d
    type(error_t) :: err
    ! y has 10 boxes: 6 ranks need 12
    call d%init(H, LOWER, UPPER, [1, 6, 1], 0, err)
    call check_error(err%code, err%message, [character(len=24) :: 'along y', '10 grid box', '6 ranks', &
                     'at least two', '12 in all'], 'too few boxes for the ranks along y')
    call err%clear()
    ! a flat scene (one box in z) is fine with one rank along z, not with two
    call d%init(H, [0.0_dp, 0.0_dp, 0.1_dp], [2.0_dp, 2.0_dp, 0.2_dp], [2, 2, 1], 3, err)
    call check(err%ok() .and. d%n_boxes(3) == 1, 'a flat scene: one box in z with one rank along z')
    call d%init(H, [0.0_dp, 0.0_dp, 0.1_dp], [2.0_dp, 2.0_dp, 0.2_dp], [1, 1, 2], 0, err)
    call check_error(err%code, err%message, [character(len=24) :: 'along z', '1 grid box', '2 ranks'], &
                     'a flat scene over two ranks along z')
    call err%clear()
    call d%init(0.0_dp, LOWER, UPPER, [1, 1, 1], 0, err)
    call check_error(err%code, err%message, [character(len=24) :: 'grid box size', '> 0'], 'box size 0')
    call err%clear()
    call d%init(H, LOWER, UPPER, [2, 1, 1], 2, err)
    call check_error(err%code, err%message, [character(len=24) :: 'rank 2', '0..1'], 'rank outside the grid')
    call err%clear()
    call d%init(H, LOWER, UPPER, [2, 0, 1], 0, err)
    call check_error(err%code, err%message, [character(len=24) :: 'dims', '>= 1'], 'dims entry 0')
    call err%clear()
    call d%init(H, [0.0_dp, ieee_nan(), 0.0_dp], UPPER, [1, 1, 1], 0, err)
    call check_error(err%code, err%message, [character(len=24) :: 'not finite'], 'NaN bounds')
    call err%clear()
  end subroutine input_errors

  !> The centre of box k [m] (exact: h is a power of two).
  pure function centre(k) result(p)
    integer(i8), intent(in) :: k(3)
    real(dp) :: p(3)
    p = (real(k, dp) + 0.5_dp)*H
  end function centre

  pure function dims_text(dims) result(text)
    integer, intent(in) :: dims(3)
    character(len=:), allocatable :: text
    character(len=40) :: buffer
    write (buffer, '(i0,1x,i0,1x,i0)') dims
    text = trim(buffer)
  end function dims_text

  real(dp) function ieee_inf()
    use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_positive_inf
    ieee_inf = ieee_value(1.0_dp, ieee_positive_inf)
  end function ieee_inf

  real(dp) function ieee_nan()
    use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
    ieee_nan = ieee_value(1.0_dp, ieee_quiet_nan)
  end function ieee_nan

end program test_domain
