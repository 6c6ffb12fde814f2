!> Migration of owned bodies between ranks at a window end (issue 18), without MPI calls of
!> its own: parallel_env moves the buffers, domain says who owns what, body_packing makes
!> the buffers. After migrate_bodies every body is owned by the rank whose brick holds its
!> centre of mass (domain%owner_of), each exactly once, its row bit for bit what it was on
!> its last owner; a rank's owned rows are in increasing global id and it holds no ghosts
!> (the caller exchanges the halo next: exchange_halo).
!>
!> The same three staged passes as the halo exchange, x then y then z, each one
!> exchange_faces call: in the pass of an axis a rank sends to the face neighbour on either
!> side the rows it holds (its own and those received in earlier passes) whose owner lies
!> on that side along the axis. A body bound for an edge or corner neighbour thus leaves
!> along x, then y, then z, forwarded by the ranks in between (a rank forwards what is not
!> its own), and arrives after at most three hops: at most 6 payload messages per rank,
!> not 26. That is only right if the new owner is a neighbour (coordinates within one of
!> this rank's along every axis): a body farther away moved more than one brick in a
!> window, faster than the halo allows, and is an error.
!>
!> The trajectory version of every body (an integer the caller bumps when a body gets a
!> new anchor) travels with it as the record's extra integer, so the new owner keeps the
!> stamps its certificates are checked against.
module migration
  use kinds, only: dp, i8
  use error_status, only: error_t, ERR_INTERNAL, ERR_NUMERIC, ERR_PARALLEL
  use string_utils, only: str, join_reals
  use parallel_env, only: parallel_t
  use domain, only: domain_t, NO_RANK
  use body_state, only: bodies_t
  use body_packing, only: unpack_bodies, pack_for_neighbour, PACK_HEADER_WORDS, PACKED_WORD_BYTES
  use halo_exchange, only: check_rank_grid
  implicit none
  private
  public :: migrate_bodies, migration_stats_t

  !> What the migrations of a run cost this rank, summed over the calls that were given it
  !> (the load/cost report, as halo_stats_t: reset it with migration_stats_t() to count
  !> one migration).
  type :: migration_stats_t
    integer(i8) :: migrations = 0
    integer(i8) :: messages_sent = 0      !< payload messages to a rank (not to MPI_PROC_NULL)
    integer(i8) :: bodies_sent = 0        !< records sent: a forwarded body counts at each hop
    integer(i8) :: bytes_sent = 0         !< payload bytes, headers included (not the lengths)
    integer(i8) :: bodies_received = 0    !< records received, forwarded ones included
    integer(i8) :: bytes_received = 0
    integer(i8) :: bodies_left = 0        !< owned bodies that left this rank for good
    integer(i8) :: bodies_arrived = 0     !< owned bodies at the end that came from elsewhere
  end type migration_stats_t

  !> Why a body stays where it is against its owner (route).
  integer, parameter :: ROUTE_OK = 0, ROUTE_NAN = 1, ROUTE_FAR = 2, ROUTE_ASTRAY = 3

contains

  !> Sends every owned body of this rank whose centre of mass is no longer in its brick
  !> (dom%owner_of) to its new owner, takes the bodies that are now its own, and leaves
  !> the owned rows in increasing global id, without ghosts. par must hold the Cartesian
  !> communicator of dom's rank grid (par%cart_create with dom%dims, dom built for
  !> par%cart_rank).
  !>
  !> versions (in): the trajectory version of owned row k (size >= n_owned); (out): those of
  !> the owned rows after, in their order. new_index(k) (size n_owned + n_ghost before):
  !> the row that row k became, 0 if it left this rank (ghost rows: always 0), so per-body
  !> arrays of the caller can follow. stats: this migration's counts added.
  !>
  !> Collective over the Cartesian communicator. Misuse every rank sees alike (no or
  !> another rank grid) returns before any message, the rows unchanged. Otherwise every
  !> rank takes part in all three passes, so none waits forever, and an error is set on the
  !> rank that found it only: the caller reduces it (par%any) as for the halo exchange. A
  !> body whose owner is not a face, edge or corner neighbour, or whose position is NaN, is
  !> such an error (naming the body, its position and both ranks); it stays on the rank
  !> holding it and every other body still migrates, so each is still held exactly once.
  !> A failure that makes this rank's routing meaningless (a domain of another rank, short
  !> versions) sends nothing more but still takes what arrives.
  !> payload (with payload_rows): more of the caller's words (a flight record: the anchor),
  !> payload(:, m) owned row payload_rows(m)'s, travelling with it bit for bit; only those
  !> rows carry one (the bodies that leave: the records of those that stay need not move).
  !> After, payload_rows lists the rows with a payload (increasing), payload(:, m) theirs.
  subroutine migrate_bodies(par, dom, bodies, err, versions, new_index, stats, payload, payload_rows)
    type(parallel_t), intent(in) :: par
    type(domain_t), intent(in) :: dom
    type(bodies_t), intent(inout) :: bodies
    type(error_t), intent(inout) :: err
    integer(i8), allocatable, intent(inout), optional :: versions(:)
    integer(i8), allocatable, intent(inout), optional :: payload(:, :)
    integer, allocatable, intent(inout), optional :: payload_rows(:)
    integer, allocatable, intent(out), optional :: new_index(:)
    type(migration_stats_t), intent(inout), optional :: stats
    ! per held row, kept in step with the rows: the extras packed with it (the version),
    ! the row it was before (0: it arrived here), the coordinates of its destination and
    ! where its payload is (> 0: that column of the caller's; < 0: of `arrived`, the
    ! payloads received; 0: none). The payload words travel in the messages only: kept in
    ! step with the rows they were copied at every pass and by the sort (36 MB for the
    ! flight records of 50,000 bodies, ten times at each full window start of a gas on two
    ! ranks), though few bodies move.
    integer(i8), allocatable :: extra(:, :), arrived(:, :), message_extra(:, :)
    integer, allocatable :: origin(:), dest(:, :), slot(:)
    integer :: n_arrived
    integer, allocatable :: rows_minus(:), rows_plus(:), keep(:), order(:)
    logical, allocatable :: leaving(:)
    real(dp), allocatable :: to_minus(:), to_plus(:), recv_minus(:), recv_plus(:)
    type(migration_stats_t) :: counts
    type(error_t) :: pass_err
    logical :: sending
    integer :: n_before, n, n_extra, n_bad, axis, neighbour(2), k, why, owner, n_version, n_payload

    n_before = bodies%n_total()
    if (present(new_index)) then
      allocate (new_index(n_before))
      new_index = 0
    end if
    call check_rank_grid(par, dom, 'migration', err)
    if (err%failed()) return
    ! from here on every rank takes part in all three passes, failed or not
    sending = .true.
    if (par%cart_rank /= dom%rank) then
      ! every destination would be computed from another rank's brick: route nothing
      call err%set(ERR_INTERNAL, 'migration: the domain is rank '//str(dom%rank)//'''s, this is rank '// &
                   str(par%cart_rank))
      sending = .false.
    end if

    ! the ghosts go (the caller exchanges the halo afresh after the owners changed); they
    ! are the last rows, so forgetting them is enough
    bodies%n_ghost = 0
    n = bodies%n_owned

    n_version = 0
    if (present(versions)) n_version = 1
    n_payload = 0
    if (present(payload) .neqv. present(payload_rows)) then
      if (err%ok()) call err%set(ERR_INTERNAL, 'migration: a payload without its rows, or rows without a payload')
      sending = .false.
    else if (present(payload)) then
      if (.not. allocated(payload_rows)) allocate (payload_rows(0))
      if (.not. allocated(payload)) allocate (payload(0, 0))
      n_payload = size(payload, 1)
      if (any(payload_rows < 1 .or. payload_rows > n) .or. size(payload, 2) < size(payload_rows)) then
        if (err%ok()) call err%set(ERR_INTERNAL, 'migration: payload rows outside the '//str(n)// &
                                   ' owned bodies, or more rows than payloads')
        sending = .false.
      end if
    end if
    n_extra = n_version + n_payload
    allocate (extra(n_version, n), slot(n), arrived(n_payload, 16))
    extra = 0
    slot = 0
    if (n_payload > 0 .and. sending) slot(payload_rows) = [(k, k=1, size(payload_rows))]
    n_arrived = 0
    if (present(versions)) then
      k = 0
      if (allocated(versions)) k = size(versions)
      if (k < n) then
        if (err%ok()) call err%set(ERR_INTERNAL, 'migration: '//str(k)//' versions for '//str(n)// &
                                   ' owned bodies')
        ! which version would go with which body is unknown: keep every body here
        sending = .false.
      else if (n > 0) then
        extra(1, :) = versions(1:n)
      end if
    end if

    origin = [(k, k=1, n)]
    allocate (dest(3, n))
    n_bad = 0
    do k = 1, n
      dest(:, k) = dom%coords
      if (.not. sending) cycle
      call route(dom, bodies%x(:, k), 0, dest(:, k), why, owner)
      if (why /= ROUTE_OK) call report(err, why, bodies%gid(k), bodies%x(:, k), owner, dom%rank, 0, n_bad)
    end do

    do axis = 1, 3
      neighbour(1) = dom%face_neighbour(2*axis - 1)     ! MINUS_X, MINUS_Y, MINUS_Z
      neighbour(2) = dom%face_neighbour(2*axis)         ! PLUS_X, ...
      n = bodies%n_owned
      rows_minus = [integer ::]
      rows_plus = [integer ::]
      if (sending) then
        rows_minus = pack([(k, k=1, n)], dest(axis, 1:n) < dom%coords(axis))
        rows_plus = pack([(k, k=1, n)], dest(axis, 1:n) > dom%coords(axis))
      end if
      ! a destination is a rank of the grid, so a side with bodies for it has a neighbour;
      ! kept here otherwise (a broken domain), never sent to MPI_PROC_NULL and lost
      if ((size(rows_minus) > 0 .and. neighbour(1) == NO_RANK) .or. &
          (size(rows_plus) > 0 .and. neighbour(2) == NO_RANK)) then
        if (err%ok()) call err%set(ERR_INTERNAL, 'migration: bodies bound beyond the rank grid along axis '// &
                                   str(axis)//' on rank '//str(dom%rank))
        if (neighbour(1) == NO_RANK) rows_minus = [integer ::]
        if (neighbour(2) == NO_RANK) rows_plus = [integer ::]
      end if
      call extras_of(rows_minus)
      call pack_for_neighbour(bodies, rows_minus, message_extra, n_extra, neighbour(1), to_minus, &
                              counts%messages_sent, counts%bodies_sent, counts%bytes_sent, by_position=.true.)
      call extras_of(rows_plus)
      call pack_for_neighbour(bodies, rows_plus, message_extra, n_extra, neighbour(2), to_plus, &
                              counts%messages_sent, counts%bodies_sent, counts%bytes_sent, by_position=.true.)
      call par%exchange_faces(axis, neighbour(1), neighbour(2), to_minus, to_plus, recv_minus, recv_plus, &
                              pass_err)
      if (pass_err%failed()) then
        ! whether anything left is unknown to this rank: keep every row (a body twice is
        ! better than a body lost) and send nothing more
        if (err%ok()) err = pass_err
        call pass_err%clear()
        sending = .false.
      else if (size(rows_minus) + size(rows_plus) > 0) then
        allocate (leaving(n))
        leaving = .false.
        leaving(rows_minus) = .true.
        leaving(rows_plus) = .true.
        counts%bodies_left = counts%bodies_left + count(leaving .and. origin(1:n) > 0)
        keep = pack([(k, k=1, n)], .not. leaving)
        call bodies%remove_rows(leaving, pass_err)
        if (pass_err%failed() .and. err%ok()) err = pass_err
        call pass_err%clear()
        origin = origin(keep)
        dest = dest(:, keep)
        extra = extra(:, keep)
        slot = slot(keep)
        deallocate (leaving)
      end if
      call take_bodies(recv_minus, neighbour(1), dom, axis, bodies, extra, n_version, n_payload, origin, dest, slot, &
                       arrived, n_arrived, counts, err, n_bad)
      call take_bodies(recv_plus, neighbour(2), dom, axis, bodies, extra, n_version, n_payload, origin, dest, slot, &
                       arrived, n_arrived, counts, err, n_bad)
    end do
    if (n_bad > 1) err%message = err%message//' (and '//str(n_bad - 1)//' more such bodies on this rank)'

    ! output and checkpoints read owned rows in gid order, and the order must not depend
    ! on which message came first: sort, carrying the per-row arrays along
    n = bodies%n_owned
    allocate (order(n))
    call bodies%sort_owned_by_gid(order)
    origin(order) = origin(1:n)
    extra(:, order) = extra(:, 1:n)
    slot(order) = slot(1:n)
    do k = 2, n
      if (bodies%gid(k) == bodies%gid(k - 1)) then
        ! two owners before, or a body kept after a failed pass that did arrive
        if (err%ok()) call err%set(ERR_INTERNAL, 'migration: body '//str(bodies%gid(k))// &
                                   ' is held twice on rank '//str(dom%rank))
        exit
      end if
    end do

    if (present(versions)) then
      if (allocated(versions)) deallocate (versions)
      allocate (versions(n))
      versions = extra(1, 1:n)
    end if
    if (present(payload) .and. present(payload_rows)) then
      ! (the rows with one, in row order)
      payload_rows = pack([(k, k=1, n)], slot(1:n) /= 0)
      if (allocated(message_extra)) deallocate (message_extra)
      allocate (message_extra(n_payload, size(payload_rows)))
      do k = 1, size(payload_rows)
        if (slot(payload_rows(k)) > 0) then
          message_extra(:, k) = payload(:, slot(payload_rows(k)))
        else
          message_extra(:, k) = arrived(:, -slot(payload_rows(k)))
        end if
      end do
      call move_alloc(message_extra, payload)
    end if
    if (present(new_index)) then
      do k = 1, n
        if (origin(k) > 0) new_index(origin(k)) = k
      end do
    end if
    counts%migrations = 1
    counts%bodies_arrived = count(origin(1:n) == 0)
    if (present(stats)) then
      stats%migrations = stats%migrations + counts%migrations
      stats%messages_sent = stats%messages_sent + counts%messages_sent
      stats%bodies_sent = stats%bodies_sent + counts%bodies_sent
      stats%bytes_sent = stats%bytes_sent + counts%bytes_sent
      stats%bodies_received = stats%bodies_received + counts%bodies_received
      stats%bytes_received = stats%bytes_received + counts%bytes_received
      stats%bodies_left = stats%bodies_left + counts%bodies_left
      stats%bodies_arrived = stats%bodies_arrived + counts%bodies_arrived
    end if
  contains
    !> The extras of the bodies of a message, in its order: each one's version and payload.
    subroutine extras_of(rows)
      integer, intent(in) :: rows(:)
      integer :: m
      if (allocated(message_extra)) deallocate (message_extra)
      allocate (message_extra(n_extra, size(rows)))
      do m = 1, size(rows)
        message_extra(1:n_version, m) = extra(:, rows(m))
        if (n_payload == 0) cycle
        if (slot(rows(m)) > 0) then
          message_extra(n_version + 1:, m) = payload(:, slot(rows(m)))
        else if (slot(rows(m)) < 0) then
          message_extra(n_version + 1:, m) = arrived(:, -slot(rows(m)))
        else
          message_extra(n_version + 1:, m) = 0
        end if
      end do
    end subroutine extras_of
  end subroutine migrate_bodies

  !> Where a body at x must go: dest, the 0-based coordinates of its owner's brick, and
  !> why = ROUTE_OK; or it stays here (dest = this rank's coordinates) because x is NaN
  !> (ROUTE_NAN, owner NO_RANK), its owner is not a neighbour (ROUTE_FAR), or, for a body
  !> received in the pass of axis `done` (0 for this rank's own), its owner is not along
  !> this rank's coordinates on the axes already exchanged (ROUTE_ASTRAY: the ranks'
  !> domains differ, as forwarding assumes they are one decomposition).
  pure subroutine route(dom, x, done, dest, why, owner)
    type(domain_t), intent(in) :: dom
    real(dp), intent(in) :: x(3)
    integer, intent(in) :: done
    integer, intent(out) :: dest(3), why, owner
    dest = dom%coords
    why = ROUTE_OK
    owner = dom%owner_of(x)
    if (owner == NO_RANK) then
      why = ROUTE_NAN
      return
    end if
    if (any(abs(dom%coords_of(owner) - dom%coords) > 1)) then
      why = ROUTE_FAR
    else if (any(dom%coords_of(owner) /= dom%coords .and. [1, 2, 3] <= done)) then
      why = ROUTE_ASTRAY
    else
      dest = dom%coords_of(owner)
    end if
  end subroutine route

  !> The error for a body that cannot go where it belongs: the first one sets err (unless
  !> an earlier error explains more) and n_bad = 1; the ones after it are counted in n_bad,
  !> so the message names one body and says how many more there were.
  subroutine report(err, why, gid, x, owner, rank, from, n_bad)
    type(error_t), intent(inout) :: err
    integer, intent(in) :: why
    integer(i8), intent(in) :: gid
    real(dp), intent(in) :: x(3)
    integer, intent(in) :: owner, rank, from
    integer, intent(inout) :: n_bad
    character(len=:), allocatable :: body_text
    if (err%failed()) then
      if (n_bad > 0) n_bad = n_bad + 1
      return
    end if
    n_bad = 1
    body_text = 'body '//str(gid)//' at ('//join_reals(x, '(g0)', ', ')//') m'
    select case (why)
    case (ROUTE_NAN)
      call err%set(ERR_NUMERIC, 'migration: '//body_text//' on rank '//str(rank)//' has a NaN position: no '// &
                   'rank owns it')
    case (ROUTE_FAR)
      call err%set(ERR_NUMERIC, 'migration: '//body_text//' belongs to rank '//str(owner)//', which is not a '// &
                   'neighbour of rank '//str(rank)//' holding it (it moved more than one brick in a window: '// &
                   'faster than the halo allows)')
    case default
      call err%set(ERR_INTERNAL, 'migration: '//body_text//' from rank '//str(from)//' belongs to rank '// &
                   str(owner)//', which rank '//str(rank)//' does not forward to (the ranks'' domains differ)')
    end select
  end subroutine report

  !> The bodies of a buffer received in the pass of `axis` appended as owned rows, with
  !> their extras, origin 0 (they arrived) and their destinations (route). Unlike ghosts
  !> they are taken even after an error on this rank: the sender has dropped them, so
  !> refusing them would lose them. An empty buffer (no neighbour, a failed pass) adds
  !> nothing; a foreign one is an error and adds nothing.
  subroutine take_bodies(buffer, neighbour, dom, axis, bodies, extra, n_version, n_payload, origin, dest, slot, &
                         arrived, n_arrived, counts, err, n_bad)
    real(dp), intent(in) :: buffer(:)
    integer, intent(in) :: neighbour
    type(domain_t), intent(in) :: dom
    integer, intent(in) :: axis
    type(bodies_t), intent(inout) :: bodies
    integer(i8), allocatable, intent(inout) :: extra(:, :), arrived(:, :)
    integer, intent(in) :: n_version, n_payload
    integer, allocatable, intent(inout) :: origin(:), dest(:, :), slot(:)
    integer, intent(inout) :: n_arrived
    type(migration_stats_t), intent(inout) :: counts
    type(error_t), intent(inout) :: err
    integer, intent(inout) :: n_bad
    type(error_t) :: unpack_err
    integer(i8), allocatable :: got(:, :), grown(:, :)
    integer, allocatable :: grown_dest(:, :)
    integer :: first, n_before, n_after, k, why, owner, n_extra, n_got
    integer(i8) :: n_sent_extra
    if (size(buffer) == 0) return
    n_extra = n_version + n_payload
    counts%bytes_received = counts%bytes_received + int(size(buffer), i8)*PACKED_WORD_BYTES
    n_sent_extra = n_extra
    if (size(buffer) >= PACK_HEADER_WORDS) n_sent_extra = transfer(buffer(4), 1_i8)
    if (n_sent_extra /= n_extra .and. err%ok()) then
      ! versions given on some ranks only: the bodies are still taken (versions 0 here)
      call err%set(ERR_PARALLEL, 'migration: rank '//str(neighbour)//' sent '//str(n_sent_extra)// &
                   ' extra integer(s) per body, this rank expects '//str(n_extra)// &
                   ' (versions given on some ranks only)')
    end if
    n_before = bodies%n_owned
    call unpack_bodies(buffer, bodies, .false., unpack_err, first, got)
    if (unpack_err%failed()) then
      call unpack_err%prefix('migration: from rank '//str(neighbour)//': ')
      if (err%ok()) err = unpack_err
      return
    end if
    n_after = bodies%n_owned
    counts%bodies_received = counts%bodies_received + (n_after - n_before)
    allocate (grown(n_version, n_after), grown_dest(3, n_after))
    grown = 0
    grown(:, 1:n_before) = extra(:, 1:n_before)
    k = min(n_version, size(got, 1))
    if (k > 0) grown(1:k, first:n_after) = got(1:k, :)
    call move_alloc(grown, extra)
    ! the payloads received go to `arrived`, their rows pointing at them
    n_got = n_after - first + 1
    slot = [slot(1:n_before), (0, k=first, n_after)]
    if (n_payload > 0 .and. n_got > 0) then
      if (n_arrived + n_got > size(arrived, 2)) then
        allocate (grown(n_payload, max(2*size(arrived, 2), n_arrived + n_got)))
        grown(:, 1:n_arrived) = arrived(:, 1:n_arrived)
        call move_alloc(grown, arrived)
      end if
      do k = first, n_after
        n_arrived = n_arrived + 1
        arrived(:, n_arrived) = 0
        if (size(got, 1) > n_version) arrived(1:min(n_payload, size(got, 1) - n_version), n_arrived) = &
          got(n_version + 1:min(n_extra, size(got, 1)), k - first + 1)
        slot(k) = -n_arrived
      end do
    end if
    grown_dest(:, 1:n_before) = dest(:, 1:n_before)
    do k = first, n_after
      call route(dom, bodies%x(:, k), axis, grown_dest(:, k), why, owner)
      if (why /= ROUTE_OK) then
        if (why /= ROUTE_NAN) why = ROUTE_ASTRAY    ! the sender checked its reach
        call report(err, why, bodies%gid(k), bodies%x(:, k), owner, dom%rank, neighbour, n_bad)
      end if
    end do
    call move_alloc(grown_dest, dest)
    origin = [origin(1:n_before), (0, k=first, n_after)]
  end subroutine take_bodies

end module migration
