!> Paths in a deck (docs/input.md): a relative mesh_file or output dir resolves against the
!> deck's folder and is stored as an absolute path, so that what a run reads and writes does
!> not depend on the folder it was started from.
module deck_paths
  use, intrinsic :: iso_c_binding, only: c_char, c_size_t, c_ptr, c_associated, c_null_char
  use string_utils, only: is_absolute_path
  implicit none
  private
  public :: resolve_path, absolute_path

contains

  !> path resolved against folder (unless absolute), as an absolute path.
  function resolve_path(folder, path) result(resolved)
    character(len=*), intent(in) :: folder, path
    character(len=:), allocatable :: resolved
    if (is_absolute_path(adjustl(path))) then
      resolved = normalise_path(trim(adjustl(path)))
    else
      resolved = absolute_path(trim(folder)//'/'//trim(adjustl(path)))
    end if
  end function resolve_path

  !> The absolute form of path (the current folder prepended to a relative path).
  function absolute_path(path) result(absolute)
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: absolute
    if (is_absolute_path(path)) then
      absolute = normalise_path(path)
    else
      absolute = normalise_path(current_folder()//'/'//path)
    end if
  end function absolute_path

  !> The current working folder (POSIX getcwd); '.' if it cannot be found.
  function current_folder() result(folder)
    character(len=:), allocatable :: folder
    interface
      function c_getcwd(buffer, size) bind(c, name='getcwd') result(p)
        import :: c_char, c_size_t, c_ptr
        character(kind=c_char), intent(out) :: buffer(*)
        integer(c_size_t), value :: size
        type(c_ptr) :: p
      end function c_getcwd
    end interface
    character(kind=c_char) :: buffer(4096)
    integer :: n
    if (.not. c_associated(c_getcwd(buffer, int(4096, c_size_t)))) then
      folder = '.'
      return
    end if
    n = 0
    do while (n < 4096)
      if (buffer(n + 1) == c_null_char) exit
      n = n + 1
    end do
    allocate (character(len=n) :: folder)
    do n = 1, len(folder)
      folder(n:n) = buffer(n)
    end do
  end function current_folder

  !> Drops empty and '.' segments ('a//./b/' -> 'a/b'); '..' is kept (symbolic links).
  pure function normalise_path(path) result(clean)
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: clean, segment
    integer :: start, slash
    logical :: absolute
    absolute = is_absolute_path(path)
    clean = ''
    start = 1
    do while (start <= len(path))
      slash = index(path(start:), '/')
      if (slash == 0) then
        segment = path(start:)
        start = len(path) + 1
      else
        segment = path(start:start + slash - 2)
        start = start + slash
      end if
      if (len(segment) == 0 .or. segment == '.') cycle
      if (len(clean) == 0) then
        clean = segment
      else
        clean = clean//'/'//segment
      end if
    end do
    if (absolute) clean = '/'//clean
    if (len(clean) == 0) clean = '.'
  end function normalise_path

end module deck_paths
