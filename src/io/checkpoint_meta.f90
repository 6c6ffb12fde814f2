!> What a checkpoint holds besides the bodies: where the run was (time, step, output
!> schedule), the reference values that drift monitors compare against, a fingerprint of
!> the deck that made it, and named statistics counters. Plain Fortran so that the build
!> without HDF5 shares it; checkpoint_io (src/io/hdf5/) reads and writes it.
module checkpoint_meta
  use kinds, only: dp, i8
  use constants, only: name_length, pi
  use error_status, only: error_t, ERR_CHECKPOINT
  use string_utils, only: str
  use body_state, only: bodies_t
  use parallel_env, only: parallel_t
  implicit none
  private
  public :: checkpoint_meta_t, checkpoint_magic, checkpoint_version, checkpoint_title_length, &
            checksum_rtol, bodies_checksum, check_checkpoint_matches

  !> Written as the root attribute 'format': files without it are not ricochet checkpoints.
  character(len=*), parameter :: checkpoint_magic = 'ricochet-checkpoint'
  !> Raised whenever the layout changes incompatibly; readers refuse other versions.
  integer, parameter :: checkpoint_version = 1
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
    !> Statistics that later parts of the run accumulate (contacts, events, ...), by name.
    real(dp), allocatable :: counters(:)
    character(len=name_length), allocatable :: counter_names(:)
  end type checkpoint_meta_t

contains

  !> Fingerprint of the bodies of a deck, the same on every rank:
  !>   sum over free bodies of gid*mass [kg]  +  pi * sum over fixed bodies of gid.
  !> Fixed bodies count by id only (their mass is "infinite"); every term is positive, so the
  !> sum has no cancellation and is reproducible to checksum_rtol in any order. Collective.
  real(dp) function bodies_checksum(par, bodies) result(checksum)
    type(parallel_t), intent(in) :: par
    type(bodies_t), intent(in) :: bodies
    integer :: i
    real(dp) :: local
    local = 0.0_dp
    do i = 1, bodies%n_owned
      if (bodies%fixed(i)) then
        local = local + pi*real(bodies%gid(i), dp)
      else
        local = local + bodies%mass(i)*real(bodies%gid(i), dp)
      end if
    end do
    checksum = par%sum(local)
  end function bodies_checksum

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
