!> What a checkpoint holds besides the bodies: where the run was (time, step, output
!> schedule), the reference values that drift monitors compare against, a fingerprint of
!> the deck that made it, and named statistics counters. Plain Fortran so that the build
!> without HDF5 shares it; checkpoint_io (src/io/hdf5/) reads and writes it.
module checkpoint_meta
  use kinds, only: dp, i8
  use constants, only: name_length, pi, line_length
  use error_status, only: error_t, ERR_CHECKPOINT
  use string_utils, only: str
  use body_state, only: bodies_t
  use parallel_env, only: parallel_t
  use digest, only: digest_t, digest_sum, digest_parts, digest_from_parts
  use exact_sum, only: exact_sum_t
  implicit none
  private
  public :: checkpoint_meta_t, checkpoint_magic, checkpoint_version, checkpoint_oldest_version, checkpoint_title_length, &
            checksum_rtol, bodies_checksum, check_checkpoint_matches, bodies_state_digest, rows_state_digest, &
            deck_line_length, shape_label_length

  !> Written as the root attribute 'format': files without it are not ricochet checkpoints.
  character(len=*), parameter :: checkpoint_magic = 'ricochet-checkpoint'
  !> Raised whenever the layout changes; readers refuse versions they do not know.
  !> Version 2 added the state digest, the shapes' geometry digests and the effective deck
  !> (deck/effective, one fixed-length string per line); version 3 stores the deck as bytes
  !> with the lines' ends (deck/text, deck/line_ends: 2.5x smaller at 100,000 bodies, and
  !> read back without padding every line to line_length). Version 2 is still read.
  integer, parameter :: checkpoint_version = 3
  integer, parameter :: checkpoint_oldest_version = 2   !< the oldest version still read
  integer, parameter :: deck_line_length = line_length   !< a line of the effective deck (paths included)
  integer, parameter :: shape_label_length = line_length  !< a shape's label (mesh paths included)
  integer, parameter :: checkpoint_title_length = 256   !< as run_config_t%title
  !> The checksum is a floating-point sum whose order depends on how bodies are spread over
  !> ranks: it is reproducible to about n_bodies*epsilon, so compare with this relative
  !> tolerance (1e-9 covers 10^6 bodies with a margin of 4000; a changed mass or a renumbered
  !> body changes it by far more).
  real(dp), parameter :: checksum_rtol = 1.0e-9_dp

  type :: checkpoint_meta_t
    character(len=32) :: magic = checkpoint_magic
    integer :: version = checkpoint_version
    real(dp) :: time = 0.0_dp                    !< simulated time of the checkpoint [s]
    integer(i8) :: step = 0                      !< steps taken so far
    integer :: n_frames = 0                      !< output frames written so far
    real(dp), allocatable :: frame_times(:)      !< (n_frames) their times [s]
    real(dp) :: next_output_time = 0.0_dp        !< [s]
    real(dp) :: next_checkpoint_time = 0.0_dp    !< [s]
    real(dp) :: wall_time_before = 0.0_dp        !< wall time of the run(s) up to here [s]
    real(dp) :: e0 = 0.0_dp                      !< reference total energy [J]
    real(dp) :: p0(3) = 0.0_dp                   !< reference linear momentum [kg m/s]
    real(dp) :: l0(3) = 0.0_dp                   !< reference angular momentum about the centre of mass [kg m^2/s]
    real(dp) :: mass0 = 0.0_dp                   !< total mass of the free bodies [kg] (momentum under gravity)
    ! Deck fingerprint: a restart must use the deck that made the checkpoint.
    integer(i8) :: n_bodies_total = 0
    character(len=checkpoint_title_length) :: title = ''
    real(dp) :: checksum = 0.0_dp                !< bodies_checksum of the deck's bodies
    !> Digest of every body row, as read (write_checkpoint computes what it stores).
    integer(i8) :: state_digest = 0
    !> Per shape of the library: its geometry digest (shape_digest) and label.
    integer(i8), allocatable :: shape_digests(:)
    character(len=shape_label_length), allocatable :: shape_labels(:)
    !> The effective deck that made the checkpoint (deck_reader effective_deck_lines):
    !> a restart compares it with its own, variable by variable. Writing: this rank's share
    !> of the lines (the shares in rank order are the deck); read back: all of them, on
    !> every rank. As wide as the longest line (at most deck_line_length): a line per
    !> variable and body, 540,000 lines for 27,000 bodies, would be 600 MB at the full width.
    character(len=:), allocatable :: deck_lines(:)
    !> Statistics that later parts of the run accumulate (contacts, events, ...), by name.
    real(dp), allocatable :: counters(:)
    character(len=name_length), allocatable :: counter_names(:)
  end type checkpoint_meta_t

contains

  !> Fingerprint of the bodies of a deck, the same on every rank:
  !>   sum over free bodies of gid*mass [kg]  +  pi * sum over fixed bodies of gid.
  !> Fixed bodies count by id only (their mass is "infinite"); every term is positive, so the
  !> sum has no cancellation. Summed exactly (exact_sum), so the value is bitwise the same
  !> for any split of the bodies over ranks and any order: the checkpoint files of runs on
  !> different rank counts are the same. Collective.
  real(dp) function bodies_checksum(par, bodies) result(checksum)
    type(parallel_t), intent(in) :: par
    type(bodies_t), intent(in) :: bodies
    integer :: i
    type(exact_sum_t) :: total
    do i = 1, bodies%n_owned
      if (bodies%fixed(i)) then
        call total%add(pi*real(bodies%gid(i), dp))
      else
        call total%add(bodies%mass(i)*real(bodies%gid(i), dp))
      end if
    end do
    call par%sum_inplace(total)
    checksum = total%value()
  end function bodies_checksum

  !> Digest of one body row: every dataset a checkpoint stores for it, bit for bit.
  pure integer(i8) function row_digest(bodies, i)
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: i
    type(digest_t) :: d
    call d%add_int8(bodies%gid(i))
    call d%add_int(bodies%shape_id(i))
    call d%add_int(bodies%group_id(i))
    call d%add_int(merge(1, 0, bodies%fixed(i)))
    call d%add_real(bodies%mass(i))
    call d%add_real(bodies%inv_mass(i))
    call d%add_reals(bodies%inertia(:, i))
    call d%add_reals(bodies%inv_inertia(:, i))
    call d%add_reals(bodies%x(:, i))
    call d%add_reals(bodies%q(:, i))
    call d%add_reals(bodies%v(:, i))
    call d%add_reals(bodies%w(:, i))
    call d%add_reals(bodies%a(:, i))
    call d%add_reals(bodies%alpha(:, i))
    row_digest = d%value()
  end function row_digest

  !> Digest of the owned bodies of every rank, independent of how they are spread over
  !> ranks and stored (collective): what write_checkpoint stores.
  integer(i8) function bodies_state_digest(par, bodies) result(value)
    type(parallel_t), intent(in) :: par
    type(bodies_t), intent(in) :: bodies
    integer(i8) :: h(2)
    h = digest_parts(rows_state_digest(bodies))
    value = digest_from_parts([par%sum(h(1)), par%sum(h(2))])
  end function bodies_state_digest

  !> The same digest of the owned rows of bodies alone (serial): what a reader compares.
  pure integer(i8) function rows_state_digest(bodies) result(value)
    type(bodies_t), intent(in) :: bodies
    integer(i8), allocatable :: rows(:)
    integer :: i
    allocate (rows(bodies%n_owned))
    do i = 1, bodies%n_owned
      rows(i) = row_digest(bodies, i)
    end do
    value = digest_sum(rows)
  end function rows_state_digest

  !> Checks that a checkpoint (meta, read from path) belongs to the deck described by
  !> expected (n_bodies_total, title, checksum filled from the deck); names every difference.
  subroutine check_checkpoint_matches(meta, expected, path, err)
    type(checkpoint_meta_t), intent(in) :: meta, expected
    character(len=*), intent(in) :: path
    type(error_t), intent(inout) :: err
    character(len=:), allocatable :: differences
    differences = ''
    if (meta%n_bodies_total /= expected%n_bodies_total) then
      differences = differences//'; number of bodies '//str(meta%n_bodies_total)//' in the checkpoint, '// &
                    str(expected%n_bodies_total)//' in the deck'
    end if
    if (trim(meta%title) /= trim(expected%title)) then
      differences = differences//"; title '"//trim(meta%title)//"' in the checkpoint, '"// &
                    trim(expected%title)//"' in the deck"
    end if
    if (.not. (abs(meta%checksum - expected%checksum) <= checksum_rtol*abs(expected%checksum))) then
      differences = differences//'; body checksum (sum of gid*mass) '//str(meta%checksum, '(es23.16)')// &
                    ' in the checkpoint, '//str(expected%checksum, '(es23.16)')// &
                    ' in the deck (masses, fixed flags or body numbering differ)'
    end if
    if (len(differences) > 0) then
      call err%set(ERR_CHECKPOINT, "checkpoint '"//trim(path)//"' was not written for this deck: "// &
                   differences(3:))
    end if
  end subroutine check_checkpoint_matches

end module checkpoint_meta
