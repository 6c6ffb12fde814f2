!> The halo exchange of the domain decomposition (issue 18), without MPI calls of its own:
!> parallel_env moves the buffers, domain says which boxes go where, body_packing makes
!> the buffers. After exchange_halo a rank holds, after its owned rows, one ghost row per
!> body whose centre of mass lies in its halo of `rings` rings (domain%in_halo), copied bit
!> for bit from the owner, ghosts in increasing global id.
!>
!> Three passes, x then y then z (domain's staged exchange): in the pass of an axis the
!> rank packs for each face neighbour along it the rows, owned and ghosts received in the
!> earlier passes, whose centre lies in domain%halo_send_boxes of that direction, and trades
!> them in one exchange_faces call (a length, then the payload, each way). Edges and
!> corners arrive by forwarding, so 6 payload messages (at most) replace 26, and each halo
!> box comes from exactly one neighbour in exactly one pass: every ghost arrives once.
!>
!> The trajectory version of every body (an integer the caller bumps when a body gets a
!> new anchor) travels with it as the record's extra integer, so the caller can tell which
!> certificates with a ghost are stale after the exchange.
module halo_exchange
  use kinds, only: dp, i8
  use error_status, only: error_t, ERR_INTERNAL, ERR_NUMERIC, ERR_PARALLEL
  use string_utils, only: str
  use parallel_env, only: parallel_t
  use domain, only: domain_t, box_range_t, MAX_HALO_RINGS
  use body_state, only: bodies_t
  use body_packing, only: unpack_bodies, pack_for_neighbour, PACK_HEADER_WORDS, PACKED_WORD_BYTES
  use sorting, only: sort_index_keys
  use, intrinsic :: ieee_arithmetic, only: ieee_is_nan
  implicit none
  private
  public :: exchange_halo, halo_stats_t, check_rank_grid

  !> What the exchanges of a run cost this rank, summed over the calls that were given it
  !> (the load/cost report: reset it with halo_stats_t() to count one exchange).
  type :: halo_stats_t
    integer(i8) :: exchanges = 0
    integer(i8) :: messages_sent = 0      !< payload messages to a rank (not to MPI_PROC_NULL)
    integer(i8) :: bodies_sent = 0        !< records sent: a forwarded body counts at each hop
    integer(i8) :: bytes_sent = 0         !< payload bytes, headers included (not the lengths)
    integer(i8) :: bodies_received = 0
    integer(i8) :: bytes_received = 0
  end type halo_stats_t


contains

  !> Replaces the ghost rows of bodies by this rank's halo of `rings` rings (1 or 2). par
  !> must hold the Cartesian communicator of domain's rank grid (par%cart_create with
  !> domain%dims, domain built for par%cart_rank). versions(k): the trajectory version of
  !> owned row k (size >= n_owned); ghost_versions(k): that of ghost row n_owned + k after
  !> the exchange (0 without versions). stats: this exchange's counts added.
  !> payload(:, k): more of the caller's words of owned row k (its flight record: the
  !> anchor), travelling with it bit for bit; ghost_payload(:, k): those of ghost row
  !> n_owned + k after the exchange (both or neither). payload_rows, when present:
  !> payload(:, k) is owned row payload_rows(k)'s instead, and only the rows this rank
  !> sends need one (those within `rings` boxes of a side with a neighbour: a caller's
  !> payload then costs what the halo does, not O(owned bodies); a row sent without one is
  !> an internal error).
  !>
  !> Collective over the Cartesian communicator. Misuse that every rank sees alike (rings,
  !> no or another rank grid) returns before any message. A failure of this rank alone (a
  !> NaN position, short versions, a bad buffer) still takes part in every pass, sending
  !> nothing more, so no rank waits forever; err says what, on this rank only: the caller
  !> reduces it (par%any) as it does for its other errors. The ghosts are then incomplete.
  subroutine exchange_halo(par, dom, bodies, rings, err, versions, ghost_versions, stats, payload, ghost_payload, &
                           payload_rows)
    type(parallel_t), intent(in) :: par
    type(domain_t), intent(in) :: dom
    type(bodies_t), intent(inout) :: bodies
    integer, intent(in) :: rings
    type(error_t), intent(inout) :: err
    integer(i8), intent(in), optional :: versions(:)
    integer(i8), allocatable, intent(out), optional :: ghost_versions(:)
    type(halo_stats_t), intent(inout), optional :: stats
    integer(i8), intent(in), optional :: payload(:, :)
    integer(i8), allocatable, intent(out), optional :: ghost_payload(:, :)
    integer, intent(in), optional :: payload_rows(:)
    !> (n_extra, ghost rows): the version, then the payload, of every ghost row (an owned
    !> row's come from versions and payload as it is sent: no copy of every owned row's)
    integer(i8), allocatable :: extra(:, :)
    integer, allocatable :: column(:)
    integer :: n0
    type(halo_stats_t) :: counts
    type(error_t) :: pass_err
    real(dp), allocatable :: recv_minus(:), recv_plus(:)
    integer :: n_extra, axis, side, direction, neighbour(2), k, n_version, n_payload
    integer, allocatable :: rows(:)
    type(box_range_t) :: boxes

    if (present(ghost_versions)) allocate (ghost_versions(0))
    n_payload = 0
    if (present(payload)) n_payload = size(payload, 1)
    if (present(ghost_payload)) allocate (ghost_payload(n_payload, 0))
    if (present(payload) .neqv. present(ghost_payload)) then
      call err%set(ERR_INTERNAL, 'halo exchange: payload and ghost_payload go together')
      return
    end if
    if (rings < 1 .or. rings > MAX_HALO_RINGS) then
      call err%set(ERR_INTERNAL, 'halo exchange: rings must be 1..'//str(MAX_HALO_RINGS)//', not '//str(rings))
      return
    end if
    call check_rank_grid(par, dom, 'halo exchange', err)
    if (err%failed()) return
    ! from here on every rank takes part in all three passes, failed or not
    if (par%cart_rank /= dom%rank) call err%set(ERR_INTERNAL, 'halo exchange: the domain is rank '// &
                                                str(dom%rank)//'''s, this is rank '//str(par%cart_rank))

    ! last exchange's ghosts go, as every ghost is sent afresh by its owner. They are the
    ! last rows, so forgetting them is enough (remove_rows would copy every owned row onto
    ! itself); the storage stays for the new ones.
    bodies%n_ghost = 0

    n_version = 0
    if (present(versions)) n_version = 1
    n_extra = n_version + n_payload
    n0 = bodies%n_owned
    allocate (extra(n_extra, 0))
    ! column(row): the payload's column of owned row row (0: none)
    allocate (column(n0))
    if (present(payload_rows)) then
      column = 0
      if (n_payload > 0) then
        if (size(payload_rows) /= size(payload, 2)) then
          call err%set(ERR_INTERNAL, 'halo exchange: '//str(size(payload_rows))//' payload rows for '// &
                       str(size(payload, 2))//' payload columns')
        else if (any(payload_rows < 1 .or. payload_rows > n0)) then
          call err%set(ERR_INTERNAL, 'halo exchange: a payload row is not an owned row')
        else
          column(payload_rows) = [(k, k=1, size(payload_rows))]
        end if
      end if
    else
      column = [(k, k=1, n0)]
      if (n_payload > 0) then
        if (size(payload, 2) < n0) call err%set(ERR_INTERNAL, 'halo exchange: payload for '// &
                                                 str(size(payload, 2))//' of '//str(n0)//' owned bodies')
      end if
    end if
    if (present(versions)) then
      if (size(versions) < n0) then
        call err%set(ERR_INTERNAL, 'halo exchange: '//str(size(versions))//' versions for '// &
                     str(n0)//' owned bodies')
      end if
    end if
    do k = 1, bodies%n_owned
      if (err%failed()) exit
      ! box_of's floor of a NaN would trap (Debug) or place the body anywhere
      if (any(ieee_is_nan(bodies%x(:, k)))) then
        call err%set(ERR_NUMERIC, 'halo exchange: body '//str(bodies%gid(k))//'''s position is NaN')
        exit
      end if
    end do

    do axis = 1, 3
      do side = 1, 2
        direction = 2*axis - 2 + side            ! MINUS_X = 1, PLUS_X = 2, ...
        neighbour(side) = dom%face_neighbour(direction)
      end do
      block
        real(dp), allocatable :: to_minus(:), to_plus(:)
        integer(i8), allocatable :: sent_extra(:, :)
        do side = 1, 2
          direction = 2*axis - 2 + side
          rows = [integer ::]
          if (err%ok() .and. neighbour(side) >= 0) then
            boxes = dom%halo_send_boxes(direction, rings)
            rows = rows_in(dom, bodies, boxes)
          end if
          call extras_of(rows, sent_extra)
          if (side == 1) then
            call pack_for_neighbour(bodies, rows, sent_extra, n_extra, neighbour(side), to_minus, &
                                    counts%messages_sent, counts%bodies_sent, counts%bytes_sent, by_position=.true.)
          else
            call pack_for_neighbour(bodies, rows, sent_extra, n_extra, neighbour(side), to_plus, &
                                    counts%messages_sent, counts%bodies_sent, counts%bytes_sent, by_position=.true.)
          end if
        end do
        call par%exchange_faces(axis, neighbour(1), neighbour(2), to_minus, to_plus, recv_minus, recv_plus, &
                                pass_err)
      end block
      ! the first error is the one that explains (a wrong domain, then its wrong neighbours)
      if (pass_err%failed() .and. err%ok()) err = pass_err
      call pass_err%clear()
      call take_ghosts(recv_minus, neighbour(1), bodies, extra, n_extra, counts, err)
      call take_ghosts(recv_plus, neighbour(2), bodies, extra, n_extra, counts, err)
    end do

    call sort_ghosts(bodies, extra, err)
    if (present(ghost_versions)) then
      deallocate (ghost_versions)
      allocate (ghost_versions(bodies%n_ghost))
      ghost_versions = 0
      if (n_version > 0) ghost_versions = extra(1, :)
    end if
    if (present(ghost_payload)) then
      deallocate (ghost_payload)
      allocate (ghost_payload(n_payload, bodies%n_ghost))
      if (n_payload > 0) ghost_payload = extra(n_version + 1:n_extra, :)
    end if
    counts%exchanges = 1
    if (present(stats)) then
      stats%exchanges = stats%exchanges + counts%exchanges
      stats%messages_sent = stats%messages_sent + counts%messages_sent
      stats%bodies_sent = stats%bodies_sent + counts%bodies_sent
      stats%bytes_sent = stats%bytes_sent + counts%bytes_sent
      stats%bodies_received = stats%bodies_received + counts%bodies_received
      stats%bytes_received = stats%bytes_received + counts%bytes_received
    end if
  contains
    !> The extras of rows (owned: version and payload column; ghosts: as they came).
    subroutine extras_of(rows, words)
      integer, intent(in) :: rows(:)
      integer(i8), allocatable, intent(out) :: words(:, :)
      integer :: m, r
      allocate (words(n_extra, size(rows)))
      if (n_extra == 0) return
      do m = 1, size(rows)
        r = rows(m)
        if (r > n0) then
          words(:, m) = extra(:, r - n0)
          cycle
        end if
        if (n_version > 0) words(1, m) = versions(r)
        if (n_payload == 0) cycle
        if (column(r) == 0) then
          words(n_version + 1:, m) = 0
          if (err%ok()) call err%set(ERR_INTERNAL, 'halo exchange: body '//str(bodies%gid(r))// &
                                     ' is sent without its payload')
          cycle
        end if
        words(n_version + 1:, m) = payload(:, column(r))
      end do
    end subroutine extras_of
  end subroutine exchange_halo

  !> The rows (owned and ghost) whose centre of mass lies in boxes (box_of: clamped to the
  !> global box, as owner_of and in_halo place a body), in row order.
  function rows_in(dom, bodies, boxes) result(rows)
    type(domain_t), intent(in) :: dom
    type(bodies_t), intent(in) :: bodies
    type(box_range_t), intent(in) :: boxes
    integer, allocatable :: rows(:)
    logical, allocatable :: inside(:)
    integer :: k
    allocate (inside(bodies%n_total()))
    inside = .false.
    if (.not. boxes%is_empty()) then
      do k = 1, bodies%n_total()
        inside(k) = boxes%holds(dom%box_of(bodies%x(:, k)))
      end do
    end if
    rows = pack([(k, k=1, bodies%n_total())], inside)
  end function rows_in

  !> The bodies of a received buffer appended as ghosts, their extras after the others'.
  !> An empty buffer (no neighbour, or one that failed) adds nothing.
  subroutine take_ghosts(buffer, neighbour, bodies, extra, n_extra, counts, err)
    real(dp), intent(in) :: buffer(:)
    integer, intent(in) :: neighbour
    type(bodies_t), intent(inout) :: bodies
    integer(i8), allocatable, intent(inout) :: extra(:, :)
    integer, intent(in) :: n_extra
    type(halo_stats_t), intent(inout) :: counts
    type(error_t), intent(inout) :: err
    integer(i8), allocatable :: got(:, :), grown(:, :)
    integer :: first, n_before
    if (size(buffer) == 0 .or. err%failed()) return
    counts%bytes_received = counts%bytes_received + int(size(buffer), i8)*PACKED_WORD_BYTES
    ! the extras' count is the header's 4th word: both sides must agree on versions or
    ! ghost_versions would be shifted (unpack_bodies checks the rest of the header)
    if (size(buffer) >= PACK_HEADER_WORDS) then
      if (transfer(buffer(4), 1_i8) /= n_extra) then
        call err%set(ERR_PARALLEL, 'halo exchange: rank '//str(neighbour)//' sent '// &
                     str(transfer(buffer(4), 1_i8))//' extra integer(s) per body, this rank expects '// &
                     str(n_extra)//' (versions given on some ranks only)')
        return
      end if
    end if
    n_before = bodies%n_ghost
    call unpack_bodies(buffer, bodies, .true., err, first, got)
    if (err%failed()) then
      call err%prefix('halo exchange: from rank '//str(neighbour)//': ')
      return
    end if
    counts%bodies_received = counts%bodies_received + (bodies%n_ghost - n_before)
    allocate (grown(n_extra, bodies%n_ghost))
    grown(:, 1:n_before) = extra(:, 1:n_before)
    if (n_extra > 0) grown(:, first - bodies%n_owned:bodies%n_ghost) = got
    call move_alloc(grown, extra)
  end subroutine take_ghosts

  !> Ghost rows (and their extras) in increasing global id, so the result does not depend
  !> on which message came first; a gid twice is a broken decomposition (two owners, or
  !> overlapping send boxes): an internal error.
  subroutine sort_ghosts(bodies, extra, err)
    type(bodies_t), intent(inout) :: bodies
    integer(i8), intent(inout) :: extra(:, :)
    type(error_t), intent(inout) :: err
    type(bodies_t) :: sorted
    integer, allocatable :: order(:)
    integer :: n0, ng, k
    n0 = bodies%n_owned
    ng = bodies%n_ghost
    if (ng < 2) return
    call sort_index_keys(reshape(bodies%gid(n0 + 1:n0 + ng), [1, ng]), order)
    do k = 2, ng
      if (bodies%gid(n0 + order(k)) == bodies%gid(n0 + order(k - 1))) then
        if (err%ok()) call err%set(ERR_INTERNAL, 'halo exchange: body '//str(bodies%gid(n0 + order(k)))// &
                                   ' arrived twice as a ghost')
        exit
      end if
    end do
    if (all(order == [(k, k=1, ng)])) return
    ! body_state moves rows only by append and remove: through a scratch copy, then the
    ! ghost rows are forgotten (the last rows, as at the start) and refilled in order
    call sorted%append_rows(bodies, n0 + order, .true.)
    bodies%n_ghost = 0
    call bodies%append_rows(sorted, [(k, k=1, ng)], .true.)
    if (size(extra, 1) > 0) extra(:, 1:ng) = extra(:, order)
  end subroutine sort_ghosts

  !> The staged exchanges' precondition, the same on every rank (so a failure returns
  !> before any message): par holds a Cartesian communicator with domain's rank grid.
  !> what names the exchange in the message.
  subroutine check_rank_grid(par, dom, what, err)
    type(parallel_t), intent(in) :: par
    type(domain_t), intent(in) :: dom
    character(len=*), intent(in) :: what
    type(error_t), intent(inout) :: err
    if (.not. par%has_cart) then
      call err%set(ERR_INTERNAL, what//': no Cartesian communicator (parallel_env cart_create)')
    else if (any(par%cart_dims /= dom%dims)) then
      call err%set(ERR_INTERNAL, what//': the domain''s rank grid '//dims_text(dom%dims)// &
                   ' is not the communicator''s '//dims_text(par%cart_dims))
    end if
  end subroutine check_rank_grid

  pure function dims_text(dims) result(text)
    integer, intent(in) :: dims(3)
    character(len=:), allocatable :: text
    text = str(dims(1))//' x '//str(dims(2))//' x '//str(dims(3))
  end function dims_text

end module halo_exchange
