!> Thin layer over the HDF5 Fortran API shared by frame_writer and checkpoint_io: parallel
!> file create/open (MPI-IO driver on the run's communicator; on one rank the default POSIX
!> driver), row-block datasets written collectively (each rank its own rows at an offset),
!> whole-dataset reads, attributes.
!>
!> Conventions:
!>  - A Fortran array (n_cols, n) is the HDF5 dataset (n, n_cols) (HDF5 reverses dimensions):
!>    one row per body / point / triangle, as ParaView and h5py expect.
!>  - Every routine does nothing when err has already failed, so a sequence of calls can be
!>    checked once at the end; close routines always run (handles are -1 when not open).
!>  - Dataset and attribute creation and writes are collective: every rank calls them with
!>    the same names and attribute values (HDF5 metadata must agree across ranks).
!>  - Types in files are fixed little-endian (f64, i64, i32) whatever the machine.
module h5_utils
  use, intrinsic :: iso_c_binding, only: c_ptr, c_loc, c_char, c_null_char
  use hdf5, only: hid_t, hsize_t, size_t, h5open_f, h5eset_auto_f, &
                  h5pcreate_f, h5pclose_f, h5pset_fapl_mpio_f, h5pset_dxpl_mpio_f, &
                  H5P_FILE_ACCESS_F, H5P_DATASET_XFER_F, H5FD_MPIO_COLLECTIVE_F, H5FD_MPIO_F, &
                  h5pget_driver_f, h5iget_file_id_f, h5fget_access_plist_f, &
                  h5fcreate_f, h5fopen_f, h5fclose_f, H5F_ACC_TRUNC_F, H5F_ACC_RDONLY_F, &
                  h5gcreate_f, h5gopen_f, h5gclose_f, h5lexists_f, &
                  h5screate_simple_f, h5screate_f, h5sclose_f, h5sselect_hyperslab_f, h5sselect_none_f, &
                  h5sget_simple_extent_ndims_f, h5sget_simple_extent_dims_f, H5S_SCALAR_F, H5S_SELECT_SET_F, &
                  h5dcreate_f, h5dopen_f, h5dclose_f, h5dget_space_f, h5dget_type_f, h5dwrite_f, h5dread_f, &
                  h5acreate_f, h5aopen_f, h5aclose_f, h5awrite_f, h5aread_f, h5aexists_f, h5aget_space_f, &
                  h5aget_type_f, h5tcopy_f, h5tclose_f, h5tset_size_f, h5tget_size_f, h5tset_strpad_f, &
                  h5tget_class_f, H5T_STR_NULLPAD_F, H5T_STRING_F, H5T_C_S1, H5T_NATIVE_DOUBLE, &
                  H5T_NATIVE_INTEGER, H5T_IEEE_F64LE, H5T_STD_I64LE, H5T_STD_I32LE, H5T_STD_U8LE, h5kind_to_type, &
                  H5_INTEGER_KIND, H5P_DATASET_CREATE_F, H5P_GROUP_CREATE_F, h5pset_obj_track_times_f, &
                  h5pset_alloc_time_f, H5D_ALLOC_TIME_EARLY_F
  use mpi_f08, only: MPI_INFO_NULL   ! a constant handle for HDF5's integer-handle API, not an MPI call
  use kinds, only: dp, i8
  use error_status, only: error_t, ERR_IO
  use parallel_env, only: parallel_t
  implicit none
  private
  public :: hid_t, h5u_start, h5u_create_parallel, h5u_open_parallel, h5u_open_serial, &
            h5u_close_file, h5u_create_group, h5u_open_group, h5u_close_group, h5u_has_attr, &
            h5u_has_link, h5u_write, h5u_write_strings, h5u_write_attr, h5u_read_attr, &
            h5u_read_real_2d, h5u_read_real_1d, h5u_read_int8_1d, h5u_read_int_1d, h5u_read_strings, &
            h5u_write_bytes, h5u_read_bytes

  integer(hid_t), parameter :: no_id = -1

  interface h5u_write
    module procedure write_real_2d, write_real_1d, write_int8_2d, write_int8_1d, write_int_1d
  end interface h5u_write

  interface h5u_write_attr
    module procedure write_attr_real, write_attr_real_array, write_attr_int, write_attr_int8, &
                     write_attr_string
  end interface h5u_write_attr

  interface h5u_read_attr
    module procedure read_attr_real, read_attr_real_array, read_attr_int, read_attr_int8, read_attr_string
  end interface h5u_read_attr

contains

  !> Initialises the HDF5 library (idempotent; makes the predefined type ids valid).
  subroutine h5u_start(err)
    type(error_t), intent(inout) :: err
    integer :: status
    if (err%failed()) return
    call h5open_f(status)
    if (status /= 0) then
      call err%set(ERR_IO, 'cannot initialise the HDF5 library')
      return
    end if
    ! HDF5 prints its error stack (HDF5-DIAG lines, dozens per failure) unless told not to.
    ! Every failure is reported once, by ricochet, naming the file: silence it for the run.
    call h5eset_auto_f(0, status)
  end subroutine h5u_start

  !> Creates (truncates) path on all ranks of par with the MPI-IO driver. Collective.
  subroutine h5u_create_parallel(par, path, file_id, err)
    type(parallel_t), intent(in) :: par
    character(len=*), intent(in) :: path
    integer(hid_t), intent(out) :: file_id
    type(error_t), intent(inout) :: err
    integer(hid_t) :: fapl
    integer :: status
    file_id = no_id
    if (err%failed()) return
    call mpio_fapl(par, fapl, err)
    if (err%failed()) return
    call h5fcreate_f(trim(path), H5F_ACC_TRUNC_F, file_id, status, access_prp=fapl)
    call h5pclose_f(fapl, status)
    if (file_id < 0) then
      file_id = no_id
      call err%set(ERR_IO, "cannot create HDF5 file '"//trim(path)//"'")
    end if
  end subroutine h5u_create_parallel

  !> Opens path read-only on all ranks of par with the MPI-IO driver. Collective. Fails
  !> (status only, the caller words the message) for files that are not HDF5 or truncated.
  subroutine h5u_open_parallel(par, path, file_id, err)
    type(parallel_t), intent(in) :: par
    character(len=*), intent(in) :: path
    integer(hid_t), intent(out) :: file_id
    type(error_t), intent(inout) :: err
    integer(hid_t) :: fapl
    integer :: status
    file_id = no_id
    if (err%failed()) return
    call mpio_fapl(par, fapl, err)
    if (err%failed()) return
    call h5fopen_f(trim(path), H5F_ACC_RDONLY_F, file_id, status, access_prp=fapl)
    call h5pclose_f(fapl, status)
    if (status /= 0 .or. file_id < 0) then
      file_id = no_id
      call err%set(ERR_IO, "cannot open '"//trim(path)//"' as an HDF5 file")
    end if
  end subroutine h5u_open_parallel

  !> Opens path read-only on this rank alone (default driver): for small reads on rank 0.
  subroutine h5u_open_serial(path, file_id, err)
    character(len=*), intent(in) :: path
    integer(hid_t), intent(out) :: file_id
    type(error_t), intent(inout) :: err
    integer :: status
    file_id = no_id
    if (err%failed()) return
    call h5fopen_f(trim(path), H5F_ACC_RDONLY_F, file_id, status)
    if (status /= 0 .or. file_id < 0) then
      file_id = no_id
      call err%set(ERR_IO, "cannot open '"//trim(path)//"' as an HDF5 file")
    end if
  end subroutine h5u_open_serial

  subroutine mpio_fapl(par, fapl, err)
    type(parallel_t), intent(in) :: par
    integer(hid_t), intent(out) :: fapl
    type(error_t), intent(inout) :: err
    integer :: status
    call h5pcreate_f(H5P_FILE_ACCESS_F, fapl, status)
    ! One rank: HDF5's default POSIX driver. MPI-IO (Open MPI's ompio) would set up shared-
    ! memory files and a semaphore for every file, about 4 ms a frame for nothing to share.
    if (status == 0 .and. par%n_ranks > 1) &
      call h5pset_fapl_mpio_f(fapl, par%comm_handle(), MPI_INFO_NULL%MPI_VAL, status)
    if (status /= 0) call err%set(ERR_IO, 'cannot set up MPI-IO file access for HDF5')
  end subroutine mpio_fapl

  !> Closes a file (collective for parallel files). Reports a failure only if err is clean:
  !> a failed close means data may not be on disk.
  subroutine h5u_close_file(file_id, err)
    integer(hid_t), intent(inout) :: file_id
    type(error_t), intent(inout) :: err
    integer :: status
    if (file_id < 0) return
    call h5fclose_f(file_id, status)
    file_id = no_id
    if (status /= 0 .and. err%ok()) call err%set(ERR_IO, 'closing the HDF5 file failed')
  end subroutine h5u_close_file

  subroutine h5u_create_group(loc, name, group_id, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    integer(hid_t), intent(out) :: group_id
    type(error_t), intent(inout) :: err
    integer(hid_t) :: gcpl
    integer :: status, close_status
    group_id = no_id
    gcpl = no_id
    if (err%failed()) return
    call h5pcreate_f(H5P_GROUP_CREATE_F, gcpl, status)
    ! (no creation times: a file is the same bytes whenever and on however many ranks it is written)
    if (status == 0) call h5pset_obj_track_times_f(gcpl, .false., status)
    if (status == 0) call h5gcreate_f(loc, name, group_id, status, gcpl_id=gcpl)
    if (gcpl >= 0) call h5pclose_f(gcpl, close_status)
    if (status /= 0) then
      group_id = no_id
      call err%set(ERR_IO, "cannot create group '"//name//"'")
    end if
  end subroutine h5u_create_group

  subroutine h5u_open_group(loc, name, group_id, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    integer(hid_t), intent(out) :: group_id
    type(error_t), intent(inout) :: err
    integer :: status
    group_id = no_id
    if (err%failed()) return
    call h5gopen_f(loc, name, group_id, status)
    if (status /= 0) then
      group_id = no_id
      call err%set(ERR_IO, "group '"//name//"' is missing")
    end if
  end subroutine h5u_open_group

  subroutine h5u_close_group(group_id)
    integer(hid_t), intent(inout) :: group_id
    integer :: status
    if (group_id < 0) return
    call h5gclose_f(group_id, status)
    group_id = no_id
  end subroutine h5u_close_group

  logical function h5u_has_attr(loc, name) result(exists)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    integer :: status
    call h5aexists_f(loc, name, exists, status)
    if (status /= 0) exists = .false.
  end function h5u_has_attr

  logical function h5u_has_link(loc, name) result(exists)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    integer :: status
    call h5lexists_f(loc, name, exists, status)
    if (status /= 0) exists = .false.
  end function h5u_has_link

  ! ---------------------------------------------------------------- datasets: writing

  !> The core of every dataset write: creates dataset `name` of n_total rows of n_cols
  !> Whether the file holding loc was opened with the MPI-IO driver (several ranks) rather
  !> than the default one (one rank; collective transfers exist only with MPI-IO).
  logical function uses_mpio(loc)
    integer(hid_t), intent(in) :: loc
    integer(hid_t) :: file_id, fapl, driver
    integer :: status
    uses_mpio = .false.
    call h5iget_file_id_f(loc, file_id, status)
    if (status /= 0) return
    call h5fget_access_plist_f(file_id, fapl, status)
    if (status == 0) then
      call h5pget_driver_f(fapl, driver, status)
      uses_mpio = status == 0 .and. driver == H5FD_MPIO_F
      call h5pclose_f(fapl, status)
    end if
    call h5fclose_f(file_id, status)
  end function uses_mpio

  !> values (rank 1 when n_cols is 0) and writes this rank's n_local rows, starting at row
  !> `offset`, from buffer, in one collective transfer.
  subroutine write_block(loc, name, file_type, mem_type, n_cols, n_total, offset, n_local, buffer, err)
    integer(hid_t), intent(in) :: loc, file_type, mem_type
    character(len=*), intent(in) :: name
    integer, intent(in) :: n_cols
    integer(i8), intent(in) :: n_total, offset
    integer, intent(in) :: n_local
    type(c_ptr), intent(in) :: buffer
    type(error_t), intent(inout) :: err
    integer(hid_t) :: file_space, mem_space, dset, xfer, dcpl
    integer(hsize_t) :: dims(2), start(2), block(2)
    integer :: rank, status
    if (err%failed()) return
    if (n_local < 0 .or. offset < 0 .or. offset + n_local > n_total) then
      call err%set(ERR_IO, "dataset '"//name//"': rows out of range (internal error)")
      return
    end if
    if (n_cols > 0) then
      rank = 2
      dims = [int(n_cols, hsize_t), int(n_total, hsize_t)]
      start = [0_hsize_t, int(offset, hsize_t)]
      block = [int(n_cols, hsize_t), int(n_local, hsize_t)]
    else
      rank = 1
      dims = [int(n_total, hsize_t), 1_hsize_t]
      start = [int(offset, hsize_t), 0_hsize_t]
      block = [int(n_local, hsize_t), 1_hsize_t]
    end if
    file_space = no_id; mem_space = no_id; dset = no_id; xfer = no_id; dcpl = no_id
    call h5screate_simple_f(rank, dims(1:rank), file_space, status)
    ! The same file bytes on any number of ranks: no creation times in object headers, and
    ! storage allocated at creation as the MPI-IO driver always does (the POSIX driver of a
    ! one-rank run would otherwise place it later).
    if (status == 0) call h5pcreate_f(H5P_DATASET_CREATE_F, dcpl, status)
    if (status == 0) call h5pset_obj_track_times_f(dcpl, .false., status)
    if (status == 0) call h5pset_alloc_time_f(dcpl, H5D_ALLOC_TIME_EARLY_F, status)
    if (status == 0) call h5dcreate_f(loc, name, file_type, file_space, dset, status, dcpl_id=dcpl)
    if (status == 0) then
      if (n_local > 0) then
        call h5sselect_hyperslab_f(file_space, H5S_SELECT_SET_F, start(1:rank), block(1:rank), status)
        if (status == 0) call h5screate_simple_f(rank, block(1:rank), mem_space, status)
      else
        ! This rank owns no rows but still takes part in the collective write.
        call h5sselect_none_f(file_space, status)
        if (status == 0) call h5screate_simple_f(1, [1_hsize_t], mem_space, status)
        if (status == 0) call h5sselect_none_f(mem_space, status)
      end if
    end if
    ! An empty dataset has no storage to write to (a collective write of nothing to it fails
    ! in HDF5 1.10 with an undefined address): creating it is all there is to do. Every rank
    ! knows n_total, so all skip together.
    if (status == 0 .and. n_total > 0) then
      call h5pcreate_f(H5P_DATASET_XFER_F, xfer, status)
      if (status == 0 .and. uses_mpio(loc)) call h5pset_dxpl_mpio_f(xfer, H5FD_MPIO_COLLECTIVE_F, status)
      if (status == 0) call h5dwrite_f(dset, mem_type, buffer, status, mem_space_id=mem_space, &
                                       file_space_id=file_space, xfer_prp=xfer)
    end if
    if (status /= 0) call err%set(ERR_IO, "cannot write dataset '"//name//"'")
    if (xfer >= 0) call h5pclose_f(xfer, status)
    if (dcpl >= 0) call h5pclose_f(dcpl, status)
    if (dset >= 0) call h5dclose_f(dset, status)
    if (mem_space >= 0) call h5sclose_f(mem_space, status)
    if (file_space >= 0) call h5sclose_f(file_space, status)
  end subroutine write_block

  !> data(n_cols, n_local): this rank's rows, written at rows offset+1.. of n_total.
  subroutine write_real_2d(loc, name, data, n_total, offset, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    real(dp), intent(in), target, contiguous :: data(:, :)
    integer(i8), intent(in) :: n_total, offset
    type(error_t), intent(inout) :: err
    real(dp), target :: dummy(1)
    if (err%failed()) return
    if (size(data) > 0) then
      call write_block(loc, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, size(data, 1), n_total, offset, &
                       size(data, 2), c_loc(data), err)
    else
      call write_block(loc, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, size(data, 1), n_total, offset, &
                       0, c_loc(dummy), err)
    end if
  end subroutine write_real_2d

  subroutine write_real_1d(loc, name, data, n_total, offset, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    real(dp), intent(in), target, contiguous :: data(:)
    integer(i8), intent(in) :: n_total, offset
    type(error_t), intent(inout) :: err
    real(dp), target :: dummy(1)
    if (err%failed()) return
    if (size(data) > 0) then
      call write_block(loc, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, 0, n_total, offset, size(data), &
                       c_loc(data), err)
    else
      call write_block(loc, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, 0, n_total, offset, 0, c_loc(dummy), err)
    end if
  end subroutine write_real_1d

  subroutine write_int8_2d(loc, name, data, n_total, offset, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    integer(i8), intent(in), target, contiguous :: data(:, :)
    integer(i8), intent(in) :: n_total, offset
    type(error_t), intent(inout) :: err
    integer(i8), target :: dummy(1)
    if (err%failed()) return
    if (size(data) > 0) then
      call write_block(loc, name, H5T_STD_I64LE, h5kind_to_type(i8, H5_INTEGER_KIND), size(data, 1), &
                       n_total, offset, size(data, 2), c_loc(data), err)
    else
      call write_block(loc, name, H5T_STD_I64LE, h5kind_to_type(i8, H5_INTEGER_KIND), size(data, 1), &
                       n_total, offset, 0, c_loc(dummy), err)
    end if
  end subroutine write_int8_2d

  subroutine write_int8_1d(loc, name, data, n_total, offset, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    integer(i8), intent(in), target, contiguous :: data(:)
    integer(i8), intent(in) :: n_total, offset
    type(error_t), intent(inout) :: err
    integer(i8), target :: dummy(1)
    if (err%failed()) return
    if (size(data) > 0) then
      call write_block(loc, name, H5T_STD_I64LE, h5kind_to_type(i8, H5_INTEGER_KIND), 0, n_total, offset, &
                       size(data), c_loc(data), err)
    else
      call write_block(loc, name, H5T_STD_I64LE, h5kind_to_type(i8, H5_INTEGER_KIND), 0, n_total, offset, &
                       0, c_loc(dummy), err)
    end if
  end subroutine write_int8_1d

  subroutine write_int_1d(loc, name, data, n_total, offset, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    integer, intent(in), target, contiguous :: data(:)
    integer(i8), intent(in) :: n_total, offset
    type(error_t), intent(inout) :: err
    integer, target :: dummy(1)
    if (err%failed()) return
    if (size(data) > 0) then
      call write_block(loc, name, H5T_STD_I32LE, H5T_NATIVE_INTEGER, 0, n_total, offset, size(data), &
                       c_loc(data), err)
    else
      call write_block(loc, name, H5T_STD_I32LE, H5T_NATIVE_INTEGER, 0, n_total, offset, 0, c_loc(dummy), err)
    end if
  end subroutine write_int_1d

  !> Text as bytes (unsigned 8-bit, any byte kept as it is): this rank's n_local bytes of
  !> text written at bytes offset+1.. of n_total. For long text of lines of unequal length
  !> (the effective deck) with their ends beside it: a fixed-length string dataset pads every
  !> line to the longest.
  subroutine h5u_write_bytes(loc, name, text, n_total, offset, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    character(len=*), intent(in) :: text
    integer(i8), intent(in) :: n_total, offset
    type(error_t), intent(inout) :: err
    character(kind=c_char), allocatable, target :: buffer(:)
    integer :: k
    if (err%failed()) return
    allocate (buffer(max(1, len(text))))
    do k = 1, len(text)
      buffer(k) = text(k:k)
    end do
    call write_block(loc, name, H5T_STD_U8LE, H5T_STD_U8LE, 0, n_total, offset, len(text), c_loc(buffer), err)
  end subroutine h5u_write_bytes

  !> Fixed-length, null-padded strings (trailing blanks of the Fortran strings dropped),
  !> one per row: what h5py and other C readers expect.
  subroutine h5u_write_strings(loc, name, strings, n_total, offset, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    character(len=*), intent(in) :: strings(:)
    integer(i8), intent(in) :: n_total, offset
    type(error_t), intent(inout) :: err
    character(kind=c_char), allocatable, target :: buffer(:, :)
    integer(hid_t) :: string_type
    integer :: i, k, width, status
    if (err%failed()) return
    width = max(1, len(strings))
    call string_type_of(width, string_type, status)
    if (status /= 0) then
      call err%set(ERR_IO, "dataset '"//name//"': cannot make a string type")
      return
    end if
    allocate (buffer(width, max(1, size(strings))))
    buffer = c_null_char
    do i = 1, size(strings)
      do k = 1, len_trim(strings(i))
        buffer(k, i) = strings(i)(k:k)
      end do
    end do
    call write_block(loc, name, string_type, string_type, 0, n_total, offset, size(strings), c_loc(buffer), err)
    call h5tclose_f(string_type, status)
  end subroutine h5u_write_strings

  subroutine string_type_of(width, string_type, status)
    integer, intent(in) :: width
    integer(hid_t), intent(out) :: string_type
    integer, intent(out) :: status
    call h5tcopy_f(H5T_C_S1, string_type, status)
    if (status == 0) call h5tset_size_f(string_type, int(width, size_t), status)
    if (status == 0) call h5tset_strpad_f(string_type, H5T_STR_NULLPAD_F, status)
  end subroutine string_type_of

  ! ---------------------------------------------------------------- datasets: reading

  !> Opens dataset name, returns its dimensions in Fortran order (dims(1) fastest) and rank.
  subroutine open_dataset(loc, name, dset, dims, rank, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    integer(hid_t), intent(out) :: dset
    integer(hsize_t), intent(out) :: dims(2)
    integer, intent(out) :: rank
    type(error_t), intent(inout) :: err
    integer(hid_t) :: space
    integer(hsize_t) :: maxdims(2)
    integer :: status
    dset = no_id
    dims = 0
    rank = 0
    if (err%failed()) return
    if (.not. h5u_has_link(loc, name)) then
      call err%set(ERR_IO, "dataset '"//name//"' is missing")
      return
    end if
    call h5dopen_f(loc, name, dset, status)
    if (status /= 0) then
      dset = no_id
      call err%set(ERR_IO, "cannot open dataset '"//name//"'")
      return
    end if
    rank = 0
    call h5dget_space_f(dset, space, status)
    if (status == 0) then
      call h5sget_simple_extent_ndims_f(space, rank, status)
      if (status == 0 .and. rank >= 1 .and. rank <= 2) then
        ! returns the rank in status on success
        call h5sget_simple_extent_dims_f(space, dims(1:rank), maxdims(1:rank), status)
        if (status /= rank) rank = 0
      else
        rank = 0
      end if
      call h5sclose_f(space, status)
    end if
    if (rank < 1 .or. rank > 2) then
      call err%set(ERR_IO, "dataset '"//name//"' has an unexpected shape")
      call h5dclose_f(dset, status)
      dset = no_id
    end if
  end subroutine open_dataset

  subroutine read_whole(dset, name, mem_type, buffer, err)
    integer(hid_t), intent(inout) :: dset
    character(len=*), intent(in) :: name
    integer(hid_t), intent(in) :: mem_type
    type(c_ptr), intent(in) :: buffer
    type(error_t), intent(inout) :: err
    type(c_ptr) :: target_buffer   ! HDF5 declares the buffer argument intent(inout)
    integer :: status
    target_buffer = buffer
    call h5dread_f(dset, mem_type, target_buffer, status)
    if (status /= 0) call err%set(ERR_IO, "cannot read dataset '"//name//"'")
  end subroutine read_whole

  subroutine close_dataset(dset)
    integer(hid_t), intent(inout) :: dset
    integer :: status
    if (dset >= 0) call h5dclose_f(dset, status)
    dset = no_id
  end subroutine close_dataset

  !> Reads all rows of a dataset of n_cols columns into data(n_cols, n_rows).
  subroutine h5u_read_real_2d(loc, name, n_cols, data, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    integer, intent(in) :: n_cols
    real(dp), allocatable, target, intent(out) :: data(:, :)
    type(error_t), intent(inout) :: err
    integer(hid_t) :: dset
    integer(hsize_t) :: dims(2)
    integer :: rank
    call open_dataset(loc, name, dset, dims, rank, err)
    if (err%failed()) return
    if (rank /= 2 .or. dims(1) /= int(n_cols, hsize_t)) then
      call err%set(ERR_IO, "dataset '"//name//"' does not have the expected number of columns")
    else
      allocate (data(n_cols, dims(2)))
      if (size(data) > 0) call read_whole(dset, name, H5T_NATIVE_DOUBLE, c_loc(data), err)
    end if
    call close_dataset(dset)
  end subroutine h5u_read_real_2d

  subroutine h5u_read_real_1d(loc, name, data, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    real(dp), allocatable, target, intent(out) :: data(:)
    type(error_t), intent(inout) :: err
    integer(hid_t) :: dset
    integer(hsize_t) :: dims(2)
    integer :: rank
    call open_dataset(loc, name, dset, dims, rank, err)
    if (err%failed()) return
    if (rank /= 1) then
      call err%set(ERR_IO, "dataset '"//name//"' is not one-dimensional")
    else
      allocate (data(dims(1)))
      if (size(data) > 0) call read_whole(dset, name, H5T_NATIVE_DOUBLE, c_loc(data), err)
    end if
    call close_dataset(dset)
  end subroutine h5u_read_real_1d

  subroutine h5u_read_int8_1d(loc, name, data, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    integer(i8), allocatable, target, intent(out) :: data(:)
    type(error_t), intent(inout) :: err
    integer(hid_t) :: dset
    integer(hsize_t) :: dims(2)
    integer :: rank
    call open_dataset(loc, name, dset, dims, rank, err)
    if (err%failed()) return
    if (rank /= 1) then
      call err%set(ERR_IO, "dataset '"//name//"' is not one-dimensional")
    else
      allocate (data(dims(1)))
      if (size(data) > 0) call read_whole(dset, name, h5kind_to_type(i8, H5_INTEGER_KIND), c_loc(data), err)
    end if
    call close_dataset(dset)
  end subroutine h5u_read_int8_1d

  subroutine h5u_read_int_1d(loc, name, data, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    integer, allocatable, target, intent(out) :: data(:)
    type(error_t), intent(inout) :: err
    integer(hid_t) :: dset
    integer(hsize_t) :: dims(2)
    integer :: rank
    call open_dataset(loc, name, dset, dims, rank, err)
    if (err%failed()) return
    if (rank /= 1) then
      call err%set(ERR_IO, "dataset '"//name//"' is not one-dimensional")
    else
      allocate (data(dims(1)))
      if (size(data) > 0) call read_whole(dset, name, H5T_NATIVE_INTEGER, c_loc(data), err)
    end if
    call close_dataset(dset)
  end subroutine h5u_read_int_1d

  !> Reads a whole byte dataset (h5u_write_bytes) as one string.
  subroutine h5u_read_bytes(loc, name, text, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    character(len=:), allocatable, intent(out) :: text
    type(error_t), intent(inout) :: err
    character(kind=c_char), allocatable, target :: buffer(:)
    integer(hid_t) :: dset
    integer(hsize_t) :: dims(2)
    integer :: rank, k
    call open_dataset(loc, name, dset, dims, rank, err)
    if (err%failed()) return
    if (rank /= 1) then
      call err%set(ERR_IO, "dataset '"//name//"' is not one-dimensional")
    else if (dims(1) > int(huge(1), hsize_t)) then
      call err%set(ERR_IO, "dataset '"//name//"' has more than 2^31 bytes")
    else
      allocate (buffer(max(1_hsize_t, dims(1))))
      if (dims(1) > 0) call read_whole(dset, name, H5T_STD_U8LE, c_loc(buffer), err)
      allocate (character(len=int(dims(1))) :: text)
      do k = 1, int(dims(1))
        text(k:k) = buffer(k)
      end do
    end if
    call close_dataset(dset)
  end subroutine h5u_read_bytes

  !> Reads a string dataset; strings longer than len(strings) are cut.
  subroutine h5u_read_strings(loc, name, strings, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    character(len=*), allocatable, intent(out) :: strings(:)
    type(error_t), intent(inout) :: err
    integer(hid_t) :: dset, file_type, mem_type
    integer(hsize_t) :: dims(2)
    integer(size_t) :: width
    character(kind=c_char), allocatable, target :: buffer(:, :)
    integer :: rank, status, i, k, class
    call open_dataset(loc, name, dset, dims, rank, err)
    if (err%failed()) return
    call h5dget_type_f(dset, file_type, status)
    if (status == 0) call h5tget_class_f(file_type, class, status)
    if (status == 0 .and. class /= H5T_STRING_F) status = -1
    if (status == 0) call h5tget_size_f(file_type, width, status)
    if (status == 0) call h5tclose_f(file_type, status)
    if (status /= 0 .or. rank /= 1) then
      call err%set(ERR_IO, "dataset '"//name//"' is not a list of strings")
      call close_dataset(dset)
      return
    end if
    allocate (strings(dims(1)))
    strings = ''
    if (dims(1) > 0) then
      allocate (buffer(width, dims(1)))
      call string_type_of(int(width), mem_type, status)
      if (status == 0) call read_whole(dset, name, mem_type, c_loc(buffer), err)
      call h5tclose_f(mem_type, status)
      do i = 1, size(strings)
        do k = 1, min(int(width), len(strings))
          if (buffer(k, i) == c_null_char) exit
          strings(i)(k:k) = buffer(k, i)
        end do
      end do
    end if
    call close_dataset(dset)
  end subroutine h5u_read_strings

  ! ---------------------------------------------------------------- attributes

  subroutine write_attr_raw(loc, name, file_type, mem_type, n, buffer, err)
    integer(hid_t), intent(in) :: loc, file_type, mem_type
    character(len=*), intent(in) :: name
    integer, intent(in) :: n   !< 0: scalar
    type(c_ptr), intent(in) :: buffer
    type(error_t), intent(inout) :: err
    integer(hid_t) :: space, attr
    integer :: status
    if (err%failed()) return
    attr = no_id
    if (n == 0) then
      call h5screate_f(H5S_SCALAR_F, space, status)
    else
      call h5screate_simple_f(1, [int(n, hsize_t)], space, status)
    end if
    if (status == 0) call h5acreate_f(loc, name, file_type, space, attr, status)
    if (status == 0) call h5awrite_f(attr, mem_type, buffer, status)
    if (status /= 0) call err%set(ERR_IO, "cannot write attribute '"//name//"'")
    if (attr >= 0) call h5aclose_f(attr, status)
    call h5sclose_f(space, status)
  end subroutine write_attr_raw

  subroutine write_attr_real(loc, name, value, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    real(dp), intent(in), target :: value
    type(error_t), intent(inout) :: err
    call write_attr_raw(loc, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, 0, c_loc(value), err)
  end subroutine write_attr_real

  subroutine write_attr_real_array(loc, name, values, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    real(dp), intent(in), target, contiguous :: values(:)
    type(error_t), intent(inout) :: err
    call write_attr_raw(loc, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, size(values), c_loc(values), err)
  end subroutine write_attr_real_array

  subroutine write_attr_int(loc, name, value, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    integer, intent(in), target :: value
    type(error_t), intent(inout) :: err
    call write_attr_raw(loc, name, H5T_STD_I32LE, H5T_NATIVE_INTEGER, 0, c_loc(value), err)
  end subroutine write_attr_int

  subroutine write_attr_int8(loc, name, value, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    integer(i8), intent(in), target :: value
    type(error_t), intent(inout) :: err
    call write_attr_raw(loc, name, H5T_STD_I64LE, h5kind_to_type(i8, H5_INTEGER_KIND), 0, c_loc(value), err)
  end subroutine write_attr_int8

  subroutine write_attr_string(loc, name, value, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    character(len=*), intent(in) :: value
    type(error_t), intent(inout) :: err
    character(kind=c_char), allocatable, target :: buffer(:)
    integer(hid_t) :: string_type
    integer :: k, width, status
    if (err%failed()) return
    width = max(1, len_trim(value))
    allocate (buffer(width))
    buffer = c_null_char
    do k = 1, len_trim(value)
      buffer(k) = value(k:k)
    end do
    call string_type_of(width, string_type, status)
    if (status /= 0) then
      call err%set(ERR_IO, "attribute '"//name//"': cannot make a string type")
      return
    end if
    call write_attr_raw(loc, name, string_type, string_type, 0, c_loc(buffer), err)
    call h5tclose_f(string_type, status)
  end subroutine write_attr_string

  !> Opens attribute name and checks it holds n values (0: scalar or one value).
  subroutine open_attr(loc, name, n, attr, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    integer, intent(in) :: n
    integer(hid_t), intent(out) :: attr
    type(error_t), intent(inout) :: err
    integer(hid_t) :: space
    integer(hsize_t) :: dims(1), maxdims(1)
    integer :: rank, status
    attr = no_id
    if (err%failed()) return
    if (.not. h5u_has_attr(loc, name)) then
      call err%set(ERR_IO, "attribute '"//name//"' is missing")
      return
    end if
    call h5aopen_f(loc, name, attr, status)
    if (status /= 0) then
      attr = no_id
      call err%set(ERR_IO, "cannot open attribute '"//name//"'")
      return
    end if
    call h5aget_space_f(attr, space, status)
    call h5sget_simple_extent_ndims_f(space, rank, status)
    dims = 1
    if (rank == 1) call h5sget_simple_extent_dims_f(space, dims, maxdims, status)
    call h5sclose_f(space, status)
    if (rank > 1 .or. dims(1) /= int(max(n, 1), hsize_t)) then
      call err%set(ERR_IO, "attribute '"//name//"' does not have the expected size")
      call h5aclose_f(attr, status)
      attr = no_id
    end if
  end subroutine open_attr

  subroutine read_attr_raw(loc, name, mem_type, n, buffer, err)
    integer(hid_t), intent(in) :: loc, mem_type
    character(len=*), intent(in) :: name
    integer, intent(in) :: n
    type(c_ptr), intent(in) :: buffer
    type(error_t), intent(inout) :: err
    integer(hid_t) :: attr
    type(c_ptr) :: target_buffer   ! HDF5 declares the buffer argument intent(inout)
    integer :: status
    call open_attr(loc, name, n, attr, err)
    if (err%failed()) return
    target_buffer = buffer
    call h5aread_f(attr, mem_type, target_buffer, status)
    if (status /= 0) call err%set(ERR_IO, "cannot read attribute '"//name//"'")
    call h5aclose_f(attr, status)
  end subroutine read_attr_raw

  subroutine read_attr_real(loc, name, value, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    real(dp), intent(inout), target :: value
    type(error_t), intent(inout) :: err
    call read_attr_raw(loc, name, H5T_NATIVE_DOUBLE, 0, c_loc(value), err)
  end subroutine read_attr_real

  subroutine read_attr_real_array(loc, name, values, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    real(dp), intent(inout), target, contiguous :: values(:)
    type(error_t), intent(inout) :: err
    call read_attr_raw(loc, name, H5T_NATIVE_DOUBLE, size(values), c_loc(values), err)
  end subroutine read_attr_real_array

  subroutine read_attr_int(loc, name, value, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    integer, intent(inout), target :: value
    type(error_t), intent(inout) :: err
    call read_attr_raw(loc, name, H5T_NATIVE_INTEGER, 0, c_loc(value), err)
  end subroutine read_attr_int

  subroutine read_attr_int8(loc, name, value, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    integer(i8), intent(inout), target :: value
    type(error_t), intent(inout) :: err
    call read_attr_raw(loc, name, h5kind_to_type(i8, H5_INTEGER_KIND), 0, c_loc(value), err)
  end subroutine read_attr_int8

  subroutine read_attr_string(loc, name, value, err)
    integer(hid_t), intent(in) :: loc
    character(len=*), intent(in) :: name
    character(len=:), allocatable, intent(inout) :: value
    type(error_t), intent(inout) :: err
    integer(hid_t) :: attr, file_type, mem_type
    integer(size_t) :: width
    character(kind=c_char), allocatable, target :: buffer(:)
    type(c_ptr) :: target_buffer
    integer :: status, class, k
    call open_attr(loc, name, 0, attr, err)
    if (err%failed()) return
    call h5aget_type_f(attr, file_type, status)
    if (status == 0) call h5tget_class_f(file_type, class, status)
    if (status == 0 .and. class /= H5T_STRING_F) status = -1
    if (status == 0) call h5tget_size_f(file_type, width, status)
    call h5tclose_f(file_type, k)
    if (status == 0) then
      allocate (buffer(width))
      call string_type_of(int(width), mem_type, status)
      target_buffer = c_loc(buffer)
      if (status == 0) call h5aread_f(attr, mem_type, target_buffer, status)
      call h5tclose_f(mem_type, k)
    end if
    call h5aclose_f(attr, k)
    if (status /= 0) then
      call err%set(ERR_IO, "attribute '"//name//"' is not a readable string")
      return
    end if
    value = ''
    do k = 1, int(width)
      if (buffer(k) == c_null_char) exit
      value = value//buffer(k)
    end do
  end subroutine read_attr_string

end module h5_utils
