!> The few file-system operations Fortran lacks (make a folder, rename, remove, test
!> access), through the C library's POSIX calls by ISO_C_BINDING: no shell, no C source.
!> rename() is atomic on POSIX file systems, which is what makes "write to a temporary
!> name, then rename" safe against crashes: readers see the old file or the new one.
module file_system
  use, intrinsic :: iso_c_binding, only: c_int, c_char, c_null_char
  use error_status, only: error_t, ERR_IO
  implicit none
  private
  public :: make_directory, rename_file, remove_file, file_exists, directory_is_writable

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

end module file_system
