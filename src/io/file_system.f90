!> The few file-system operations Fortran lacks (make a folder, rename, remove, test
!> access, writes whose failure is reported), through the C library by ISO_C_BINDING.
!> rename() is atomic on POSIX file systems, which is what makes "write to a temporary
!> name, then rename" safe against crashes: readers see the old file or the new one.
module file_system
  use, intrinsic :: iso_c_binding, only: c_int, c_char, c_null_char, c_ptr, c_null_ptr, c_size_t, &
                                         c_associated, c_loc
  use error_status, only: error_t, ERR_IO
  implicit none
  private
  public :: make_directory, rename_file, remove_file, file_exists, directory_is_writable, &
            write_file_atomically, stream_t, stream_open, stream_write, stream_close

  !> A file written through C stdio (see stream_open).
  type :: stream_t
    type(c_ptr) :: handle = c_null_ptr
    character(len=:), allocatable :: path
  end type stream_t

  integer(c_int), parameter :: W_OK = 2_c_int   !< access(2): write permission
  integer(c_int), parameter :: X_OK = 1_c_int   !< access(2): search permission (folders)
  integer(c_int), parameter :: F_OK = 0_c_int   !< access(2): exists
  !> rwxr-xr-x before the umask: the usual mode for a folder of results.
  integer(c_int), parameter :: folder_mode = int(o'755', c_int)

  interface
    integer(c_int) function c_mkdir(path, mode) bind(C, name='mkdir')
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int), value :: mode
    end function c_mkdir
    integer(c_int) function c_rename(old_path, new_path) bind(C, name='rename')
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: old_path(*), new_path(*)
    end function c_rename
    integer(c_int) function c_remove(path) bind(C, name='remove')
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: path(*)
    end function c_remove
    integer(c_int) function c_access(path, mode) bind(C, name='access')
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int), value :: mode
    end function c_access
    type(c_ptr) function c_fopen(path, mode) bind(C, name='fopen')
      import :: c_ptr, c_char
      character(kind=c_char), intent(in) :: path(*), mode(*)
    end function c_fopen
    integer(c_size_t) function c_fwrite(buffer, size, count, stream) bind(C, name='fwrite')
      import :: c_ptr, c_size_t
      type(c_ptr), value :: buffer, stream
      integer(c_size_t), value :: size, count
    end function c_fwrite
    integer(c_int) function c_fflush(stream) bind(C, name='fflush')
      import :: c_int, c_ptr
      type(c_ptr), value :: stream
    end function c_fflush
    integer(c_int) function c_fclose(stream) bind(C, name='fclose')
      import :: c_int, c_ptr
      type(c_ptr), value :: stream
    end function c_fclose
  end interface

contains

  !> Creates a folder and its missing parents (like mkdir -p). Succeeds when the folder
  !> exists afterwards and is writable; every failure before that is not an error by itself
  !> (the folder may exist already, or another rank may have just made it).
  subroutine make_directory(path, err)
    character(len=*), intent(in) :: path
    type(error_t), intent(inout) :: err
    integer :: i, length
    integer(c_int) :: status
    length = len_trim(path)
    if (length == 0) then
      call err%set(ERR_IO, 'cannot create a folder with an empty name')
      return
    end if
    do i = 2, length
      if (path(i:i) == '/' .and. path(i - 1:i - 1) /= '/') status = c_mkdir(path(1:i - 1)//c_null_char, folder_mode)
    end do
    status = c_mkdir(path(1:length)//c_null_char, folder_mode)
    if (.not. directory_is_writable(path)) then
      call err%set(ERR_IO, "cannot create the folder '"//trim(path)//"' (or it is not writable)")
    end if
  end subroutine make_directory

  logical function directory_is_writable(path)
    character(len=*), intent(in) :: path
    directory_is_writable = c_access(trim(path)//c_null_char, ior(W_OK, X_OK)) == 0
  end function directory_is_writable

  logical function file_exists(path)
    character(len=*), intent(in) :: path
    file_exists = c_access(trim(path)//c_null_char, F_OK) == 0
  end function file_exists

  !> Atomically replaces new_path by old_path (same file system).
  subroutine rename_file(old_path, new_path, err)
    character(len=*), intent(in) :: old_path, new_path
    type(error_t), intent(inout) :: err
    if (c_rename(trim(old_path)//c_null_char, trim(new_path)//c_null_char) /= 0) then
      call err%set(ERR_IO, "cannot rename '"//trim(old_path)//"' to '"//trim(new_path)//"'")
    end if
  end subroutine rename_file

  !> Removes a file if it exists; a missing file is not an error.
  subroutine remove_file(path, err)
    character(len=*), intent(in) :: path
    type(error_t), intent(inout) :: err
    if (.not. file_exists(path)) return
    if (c_remove(trim(path)//c_null_char) /= 0) then
      call err%set(ERR_IO, "cannot remove '"//trim(path)//"'")
    end if
  end subroutine remove_file

  !> Opens path with C stdio (mode 'w': replace, 'a': append). gfortran's own I/O does not
  !> report a write that fails for a full disk or a file-size limit (the data is lost and
  !> iostat stays 0), so files that must never be silently short go through these calls,
  !> whose every result is checked.
  subroutine stream_open(path, mode, stream, err)
    character(len=*), intent(in) :: path, mode
    type(stream_t), intent(out) :: stream
    type(error_t), intent(inout) :: err
    if (err%failed()) return
    stream%path = trim(path)
    stream%handle = c_fopen(stream%path//c_null_char, mode//c_null_char)
    if (.not. c_associated(stream%handle)) call err%set(ERR_IO, "cannot open '"//stream%path//"' for writing")
  end subroutine stream_open

  !> Writes text (and a newline if line) and hands it to the kernel (fflush), so a run that
  !> stops later keeps it; fails, naming the file, when not all of it was written.
  subroutine stream_write(stream, text, err, line)
    type(stream_t), intent(inout) :: stream
    character(len=*), intent(in) :: text
    type(error_t), intent(inout) :: err
    logical, intent(in), optional :: line
    character(kind=c_char, len=:), allocatable, target :: buffer
    logical :: newline
    if (err%failed()) return
    if (.not. c_associated(stream%handle)) then
      call err%set(ERR_IO, "'"//stream%path//"' written while not open")
      return
    end if
    newline = .false.
    if (present(line)) newline = line
    buffer = text
    if (newline) buffer = buffer//new_line('a')
    if (len(buffer) > 0) then
      if (c_fwrite(c_loc(buffer), 1_c_size_t, int(len(buffer), c_size_t), stream%handle) /= &
          int(len(buffer), c_size_t)) then
        call err%set(ERR_IO, "cannot write to '"//stream%path//"' (disk full or file size limit?)")
        return
      end if
    end if
    if (c_fflush(stream%handle) /= 0) &
      call err%set(ERR_IO, "cannot write to '"//stream%path//"' (disk full or file size limit?)")
  end subroutine stream_write

  !> Closes the stream; a failed close (the last data not written) is an error unless err
  !> already holds one.
  subroutine stream_close(stream, err)
    type(stream_t), intent(inout) :: stream
    type(error_t), intent(inout) :: err
    integer(c_int) :: status
    if (.not. c_associated(stream%handle)) return
    status = c_fclose(stream%handle)
    stream%handle = c_null_ptr
    if (status /= 0 .and. err%ok()) &
      call err%set(ERR_IO, "cannot write to '"//stream%path//"' (disk full or file size limit?)")
  end subroutine stream_close

  !> Replaces path by a file holding `text`: written to path.tmp, every write and the close
  !> checked, then renamed over path. On failure path.tmp is removed and path keeps its
  !> previous content.
  subroutine write_file_atomically(path, text, err)
    character(len=*), intent(in) :: path, text
    type(error_t), intent(inout) :: err
    type(stream_t) :: stream
    type(error_t) :: ignored
    if (err%failed()) return
    call stream_open(trim(path)//'.tmp', 'w', stream, err)
    call stream_write(stream, text, err)
    call stream_close(stream, err)
    if (err%failed()) then
      call remove_file(trim(path)//'.tmp', ignored)
      call err%prefix("'"//trim(path)//"' is left as it was: ")
      return
    end if
    call rename_file(trim(path)//'.tmp', path, err)
  end subroutine write_file_atomically

end module file_system
