!> Global-id blocks: the layout of every file ricochet writes (frames, checkpoints). Rank r
!> of p holds the ids (n r)/p + 1 .. (n (r + 1))/p of n; the bodies a rank owns in the run
!> (the brick of their centre, docs/architecture.md "Domain decomposition") are brought to
!> the ranks of their blocks for a write (gather_gid_blocks), so that each rank writes one
!> contiguous row block at its MPI_Exscan offset and the file is the same, byte for byte,
!> whatever the rank count and whoever owned which body. MPI-free: parallel_env moves the
!> words (one all-to-all), body_packing makes them.
module gid_blocks
  use kinds, only: dp, i8
  use error_status, only: error_t, ERR_INTERNAL
  use string_utils, only: str
  use parallel_env, only: parallel_t
  use body_state, only: bodies_t
  use body_packing, only: pack_bodies, unpack_blocks
  implicit none
  private
  public :: gid_block, block_rank_of, gather_gid_blocks

contains

  !> Ids first..last of rank `rank` of `n_ranks` (first > last: none).
  pure subroutine gid_block(n_total, rank, n_ranks, first, last)
    integer(i8), intent(in) :: n_total
    integer, intent(in) :: rank, n_ranks
    integer(i8), intent(out) :: first, last
    first = (n_total*rank)/n_ranks + 1
    last = (n_total*(rank + 1))/n_ranks
  end subroutine gid_block

  !> The rank whose block holds global id gid (1..n_total).
  pure integer function block_rank_of(gid, n_total, n_ranks) result(rank)
    integer(i8), intent(in) :: gid, n_total
    integer, intent(in) :: n_ranks
    integer(i8) :: first, last
    rank = int(min(max(((gid - 1)*n_ranks)/max(n_total, 1_i8), 0_i8), int(n_ranks - 1, i8)))
    do
      call gid_block(n_total, rank, n_ranks, first, last)
      if (gid > last .and. rank < n_ranks - 1) then
        rank = rank + 1
      else if (gid < first .and. rank > 0) then
        rank = rank - 1
      else
        exit
      end if
    end do
  end function block_rank_of

  !> blocks: this rank's global-id block of the bodies every rank owns (bodies' owned rows,
  !> bit for bit, in increasing id), for any ownership. Collective. Every id 1..n_total must
  !> be owned exactly once over the ranks: a missing or doubled id is an error (the ranks
  !> agree on it only if the caller reduces err; the writers do).
  subroutine gather_gid_blocks(par, bodies, n_total, blocks, err)
    type(parallel_t), intent(in) :: par
    type(bodies_t), intent(in) :: bodies
    integer(i8), intent(in) :: n_total
    type(bodies_t), intent(inout) :: blocks
    type(error_t), intent(inout) :: err
    integer, allocatable :: dest(:), rows(:), counts(:), order(:)
    real(dp), allocatable :: send(:), part(:), recv(:)
    integer(i8) :: first, last
    integer :: n, r, k
    n = bodies%n_owned
    allocate (dest(n), counts(0:par%n_ranks - 1))
    do k = 1, n
      dest(k) = block_rank_of(bodies%gid(k), n_total, par%n_ranks)
    end do
    ! one packed buffer (header and records) per destination, in rank order
    allocate (send(0))
    do r = 0, par%n_ranks - 1
      rows = pack([(k, k=1, n)], dest == r)
      call pack_bodies(bodies, rows, part)
      counts(r) = size(part)
      send = [send, part]
    end do
    call par%alltoallv(send, counts, recv, err)
    deallocate (send)
    call gid_block(n_total, par%rank, par%n_ranks, first, last)
    call blocks%free()
    call blocks%allocate(int(max(last - first + 1, 0_i8)))
    blocks%n_owned = 0
    blocks%n_ghost = 0
    if (err%failed()) return
    call unpack_blocks(recv, blocks, err)
    if (err%failed()) return
    allocate (order(blocks%n_owned))
    call blocks%sort_owned_by_gid(order)
    do k = 1, blocks%n_owned
      if (blocks%gid(k) /= first + k - 1) then
        call err%set(ERR_INTERNAL, 'output: rank '//str(par%rank)//' should write bodies '//str(first)//'..'// &
                     str(last)//' but body '//str(first + k - 1)//' is owned by no rank or by two')
        return
      end if
    end do
    if (int(blocks%n_owned, i8) /= max(last - first + 1, 0_i8)) call err%set(ERR_INTERNAL, 'output: rank '// &
      str(par%rank)//' received '//str(blocks%n_owned)//' of its '//str(max(last - first + 1, 0_i8))// &
      ' bodies (a body owned by no rank)')
  end subroutine gather_gid_blocks

end module gid_blocks
