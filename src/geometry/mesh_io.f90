!> Mesh file readers: Wavefront OBJ, STL (binary and ASCII) and OFF. Every reader produces a
!> triangle soup (vertices as listed, triangles indexing them); the soup is then scaled,
!> welded (vertices closer than a tolerance merged, so STL files and triangle soups become
!> connected surfaces), cleared of degenerate triangles and handed to mesh_topology, which
!> checks it is a closed, manifold, consistently oriented surface and turns normals outward.
!> Files are read whole into memory with stream access and parsed in place: no per-line
!> I/O statements, no line-length limit, and numbers are converted by a scanner that is
!> exact (correctly rounded) and much faster than list-directed internal reads.
module mesh_io
  use, intrinsic :: iso_fortran_env, only: int32, int64, real32
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kinds, only: dp, i8
  use mesh, only: mesh_t
  use mesh_topology, only: build_mesh_topology
  use mesh_self_intersection, only: find_self_intersections, self_intersection_stats_t
  use error_status, only: error_t, ERR_MESH, ERR_IO, ERR_INPUT
  use string_utils, only: str, lower
  implicit none
  private
  public :: read_mesh_file, mesh_read_stats_t, supported_mesh_extensions

  character(len=*), parameter :: supported_mesh_extensions = &
                                 '.obj (Wavefront), .stl (binary or ASCII), .off (Object File Format)'
  !> Vertices closer than this times the bounding-box diagonal are one node: far above
  !> double round-off (1e-16), far below the spacing of vertices printed with 6 to 8
  !> significant digits, so copies of one corner merge and distinct corners never do.
  real(dp), parameter :: weld_tolerance = 1.0e-9_dp
  !> Triangles with area below this times diagonal^2 carry no surface: they are dropped.
  real(dp), parameter :: degenerate_area_tolerance = 1.0e-14_dp
  !> Faces closer than this times the diagonal touch rather than cross (self-intersection
  !> check): ten times the welding tolerance, so that a vertex meant to lie on a face but
  !> off it by the rounding of coordinates printed with 8 significant digits (5e-9 of their
  !> size) touches it; a crossing that shallow changes the volume by a relative 1e-8 at most.
  real(dp), parameter :: self_intersection_tolerance = 1.0e-8_dp
  !> Powers of ten that are exact in double precision (Clinger's fast path: a mantissa
  !> below 2^53 times or divided by one of these is a single correctly rounded operation).
  real(dp), parameter :: exact_powers_of_ten(0:22) = [1.0e0_dp, 1.0e1_dp, 1.0e2_dp, 1.0e3_dp, &
    1.0e4_dp, 1.0e5_dp, 1.0e6_dp, 1.0e7_dp, 1.0e8_dp, 1.0e9_dp, 1.0e10_dp, 1.0e11_dp, 1.0e12_dp, &
    1.0e13_dp, 1.0e14_dp, 1.0e15_dp, 1.0e16_dp, 1.0e17_dp, 1.0e18_dp, 1.0e19_dp, 1.0e20_dp, &
    1.0e21_dp, 1.0e22_dp]

  !> What reading a file did to it, for logs and tests.
  type :: mesh_read_stats_t
    integer :: n_file_vertices = 0         !< vertices as listed (3 per facet for STL)
    integer :: n_file_triangles = 0        !< triangles after fan triangulation of polygons
    integer :: n_merged_vertices = 0       !< vertices welded onto an earlier one
    integer :: n_degenerate_triangles = 0  !< dropped: repeated node after welding, or no area
    integer :: n_unused_nodes = 0          !< vertices no kept triangle uses (dropped)
    integer(i8) :: n_pair_tests = 0        !< face pairs the self-intersection check tested
    !> wall time [s] of each stage: reading and parsing the file, welding (with the removal
    !> of degenerate triangles), topology, self-intersection check
    real(dp) :: seconds_parse = 0.0_dp
    real(dp) :: seconds_weld = 0.0_dp
    real(dp) :: seconds_topology = 0.0_dp
    real(dp) :: seconds_self_intersection = 0.0_dp
  end type mesh_read_stats_t

  !> Triangles as read, before welding.
  type :: soup_t
    integer :: nv = 0
    integer :: nt = 0
    real(dp), allocatable :: verts(:, :)   !< (3, nv) [file units]
    integer, allocatable :: tris(:, :)     !< (3, nt) 1-based vertex indices
    integer, allocatable :: tri_line(:)    !< (nt) line of the face statement (OBJ)
  end type soup_t

contains

  !> Reads a closed triangle surface from path; the format follows the extension
  !> (case-insensitive). Coordinates are multiplied by scale (default 1). On success m has
  !> its topology built, outward normals and m%source = path; on error m is empty and err
  !> says which file, which line (syntax) or which edge (topology) is wrong; err is only
  !> written on failure.
  subroutine read_mesh_file(path, m, err, scale, stats)
    character(len=*), intent(in) :: path
    type(mesh_t), intent(out) :: m
    type(error_t), intent(inout) :: err
    real(dp), intent(in), optional :: scale
    type(mesh_read_stats_t), intent(out), optional :: stats
    character(len=:), allocatable :: file, ext, text
    type(soup_t) :: s
    type(mesh_read_stats_t) :: info
    type(error_t) :: e   ! local, so that an error the caller already holds does not stop the read
    integer :: dot, slash
    real(dp) :: clock

    file = trim(path)
    dot = index(file, '.', back=.true.)
    slash = index(file, '/', back=.true.)
    ext = ''
    if (dot > slash + 1) ext = lower(file(dot:))
    if (ext /= '.obj' .and. ext /= '.stl' .and. ext /= '.off') then
      call err%set(ERR_INPUT, "mesh file '"//file//"': unknown format (extension '"//ext &
                   //"'); supported: "//supported_mesh_extensions)
      return
    end if
    if (present(scale)) then
      if (.not. (ieee_is_finite(scale) .and. scale > 0.0_dp)) then
        call err%set(ERR_INPUT, "mesh file '"//file//"': scale must be a positive number, got "//str(scale))
        return
      end if
    end if

    clock = wall_seconds()
    call read_whole_file(file, text, e)
    if (e%failed()) then
      call err%set(e%code, e%message)
      return
    end if
    select case (ext)
    case ('.obj')
      call parse_obj(text, file, s, e)
    case ('.stl')
      call parse_stl(text, file, s, e)
    case ('.off')
      call parse_off(text, file, s, e)
    end select
    deallocate (text)
    if (e%failed()) then
      call err%set(e%code, e%message)
      return
    end if

    if (present(scale)) s%verts(:, 1:s%nv) = scale*s%verts(:, 1:s%nv)
    clock = wall_seconds() - clock
    call soup_to_mesh(s, file, m, info, e)
    info%seconds_parse = clock
    if (present(stats)) stats = info
    if (e%failed()) then
      call m%free()
      call err%set(e%code, e%message)
    end if
  end subroutine read_mesh_file

  !> The whole file as one string (stream access: byte exact, any line length).
  subroutine read_whole_file(path, text, err)
    character(len=*), intent(in) :: path
    character(len=:), allocatable, intent(out) :: text
    type(error_t), intent(inout) :: err
    integer :: unit, ios
    integer(int64) :: n_bytes
    logical :: exists
    character(len=512) :: msg

    inquire (file=path, exist=exists)
    if (.not. exists) then
      call err%set(ERR_IO, "mesh file '"//path//"' does not exist")
      return
    end if
    open (newunit=unit, file=path, access='stream', form='unformatted', action='read', status='old', &
          iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call err%set(ERR_IO, "cannot open mesh file '"//path//"': "//trim(msg))
      return
    end if
    inquire (unit=unit, size=n_bytes)
    if (n_bytes <= 0 .or. n_bytes > huge(1)) then
      close (unit)
      if (n_bytes == 0) then
        call err%set(ERR_MESH, "mesh file '"//path//"' is empty")
      else
        call err%set(ERR_IO, "cannot read mesh file '"//path//"': size "//str(n_bytes) &
                     //" bytes (unknown, or above the 2 GiB limit of this reader)")
      end if
      return
    end if
    allocate (character(len=n_bytes) :: text)
    read (unit, iostat=ios, iomsg=msg) text
    close (unit)
    if (ios /= 0) then
      call err%set(ERR_IO, "cannot read mesh file '"//path//"': "//trim(msg))
      deallocate (text)
    end if
  end subroutine read_whole_file

  ! ---------------------------------------------------------------------------------------
  ! Wavefront OBJ
  ! ---------------------------------------------------------------------------------------

  !> v x y z [w]; f a b c ... with a, a/t, a/t/n or a//n, negative indices counting back
  !> from the last vertex read; polygons fan-triangulated. Texture, normal, grouping,
  !> material and line statements are ignored; anything else is an error (curves or
  !> surfaces would otherwise vanish silently).
  subroutine parse_obj(text, path, s, err)
    character(len=*), intent(in) :: text, path
    type(soup_t), intent(out) :: s
    type(error_t), intent(inout) :: err
    integer :: pos, first, last, line_no, t
    integer, allocatable :: poly(:)

    call soup_reserve(s, 1024, 2048)
    allocate (poly(16))
    pos = 1
    line_no = 0
    do while (pos <= len(text))
      call next_line(text, pos, first, last)
      line_no = line_no + 1
      if (last < first) cycle
      call obj_line(text(first:last))
      if (err%failed()) return
    end do
    ! Indices may point forward in the file: checked once all vertices are known.
    do t = 1, s%nt
      if (maxval(s%tris(:, t)) > s%nv) then
        call err%set(ERR_MESH, at_line(s%tri_line(t))//'face refers to vertex '//str(maxval(s%tris(:, t))) &
                     //' but the file defines only '//str(s%nv)//' vertices')
        return
      end if
    end do

  contains

    function at_line(line) result(prefix)
      integer, intent(in) :: line
      character(len=:), allocatable :: prefix
      prefix = "mesh file '"//path//"', line "//str(line)//": "
    end function at_line

    subroutine obj_line(line)
      character(len=*), intent(in) :: line
      integer :: p, t1, t2, k, n_corners, idx
      real(dp) :: xyz(3)
      logical :: ok
      p = 1
      call next_token(line, p, t1, t2)
      if (t1 > t2) return
      if (line(t1:t1) == '#') return
      select case (line(t1:t2))
      case ('v')
        do k = 1, 3
          call next_token(line, p, t1, t2)
          if (t1 > t2) then
            call err%set(ERR_MESH, at_line(line_no)//'vertex needs 3 coordinates, found '//str(k - 1))
            return
          end if
          call parse_real(line(t1:t2), xyz(k), ok)
          if (.not. ok) then
            call err%set(ERR_MESH, at_line(line_no)//"cannot read vertex coordinate '"//line(t1:t2)//"'")
            return
          end if
        end do
        call soup_add_vertex(s, xyz)
      case ('f')
        n_corners = 0
        do
          call next_token(line, p, t1, t2)
          if (t1 > t2) exit
          if (line(t1:t1) == '#') exit
          call parse_obj_corner(line(t1:t2), idx, ok)
          if (.not. ok) then
            call err%set(ERR_MESH, at_line(line_no)//"cannot read face vertex '"//line(t1:t2) &
                         //"' (expected a, a/t, a/t/n or a//n with integer indices)")
            return
          end if
          if (idx == 0) then
            call err%set(ERR_MESH, at_line(line_no)//'face vertex index 0 (OBJ indices start at 1)')
            return
          end if
          if (idx < 0) then
            ! Relative index: -1 is the last vertex read so far.
            if (s%nv + 1 + idx < 1) then
              call err%set(ERR_MESH, at_line(line_no)//'relative face vertex index '//str(idx) &
                           //' reaches before the first vertex (only '//str(s%nv)//' read so far)')
              return
            end if
            idx = s%nv + 1 + idx
          end if
          if (n_corners == size(poly)) poly = [poly, poly]
          n_corners = n_corners + 1
          poly(n_corners) = idx
        end do
        if (n_corners < 3) then
          call err%set(ERR_MESH, at_line(line_no)//'face with '//str(n_corners)//' vertices (at least 3 needed)')
          return
        end if
        do k = 2, n_corners - 1
          call soup_add_triangle(s, [poly(1), poly(k), poly(k + 1)], line_no)
        end do
      case ('vt', 'vn', 'vp', 'g', 'o', 's', 'usemtl', 'mtllib', 'l', 'p')
        continue
      case default
        call err%set(ERR_MESH, at_line(line_no)//"unknown OBJ statement '"//line(t1:t2) &
                     //"' (read: v, f; ignored: vt, vn, vp, g, o, s, usemtl, mtllib, l, p)")
      end select
    end subroutine obj_line

  end subroutine parse_obj

  !> Vertex index of an OBJ face corner 'a', 'a/t', 'a/t/n' or 'a//n' (t and n ignored,
  !> but they must be integers or empty).
  pure subroutine parse_obj_corner(token, index, ok)
    character(len=*), intent(in) :: token
    integer, intent(out) :: index
    logical, intent(out) :: ok
    integer :: slash, i, n_slashes
    slash = scan(token, '/')
    if (slash == 0) then
      call parse_int(token, index, ok)
      return
    end if
    call parse_int(token(1:slash - 1), index, ok)
    if (.not. ok) return
    n_slashes = 0
    do i = slash, len(token)
      if (token(i:i) == '/') then
        n_slashes = n_slashes + 1
      else if (.not. (token(i:i) == '-' .or. (token(i:i) >= '0' .and. token(i:i) <= '9'))) then
        ok = .false.
      end if
    end do
    if (n_slashes > 2) ok = .false.
  end subroutine parse_obj_corner

  ! ---------------------------------------------------------------------------------------
  ! STL
  ! ---------------------------------------------------------------------------------------

  !> Binary when the size is exactly 84 + 50 n for the triangle count n in the header
  !> (binary files may also begin with "solid", so the size decides first); otherwise
  !> ASCII, which must begin with "solid".
  subroutine parse_stl(text, path, s, err)
    character(len=*), intent(in) :: text, path
    type(soup_t), intent(out) :: s
    type(error_t), intent(inout) :: err
    integer(int64) :: n_announced
    integer :: i

    n_announced = -1
    if (len(text) >= 84) then
      n_announced = int(transfer(text(81:84), 0_int32), int64)
      if (n_announced < 0) n_announced = n_announced + 2_int64**32   ! the count is unsigned
      if (84_int64 + 50_int64*n_announced == len(text, int64)) then
        call parse_stl_binary(text, path, int(n_announced), s, err)
        return
      end if
    end if
    ! ASCII: begins with "solid" and holds no NUL byte (binary float data nearly always
    ! does, so a truncated binary file beginning with "solid" is reported as such).
    i = verify(text(1:min(len(text), 4096)), ' '//achar(9)//achar(10)//achar(13))
    if (i > 0 .and. i + 4 <= len(text)) then
      if (lower(text(i:i + 4)) == 'solid' .and. index(text, achar(0)) == 0) then
        call parse_stl_ascii(text, path, s, err)
        return
      end if
    end if
    if (n_announced >= 0 .and. index(text, achar(0)) > 0) then
      call err%set(ERR_MESH, "mesh file '"//path//"' is not a valid STL file: it holds binary data but its " &
                   //'header announces '//str(n_announced)//' triangles, i.e. '//str(84_int64 + 50_int64*n_announced) &
                   //' bytes, and the file has '//str(len(text))//' bytes (truncated or corrupt)')
    else if (n_announced >= 0) then
      call err%set(ERR_MESH, "mesh file '"//path//"' is not a valid STL file: it does not begin with 'solid' " &
                   //"(ASCII) and as binary its header announces "//str(n_announced)//' triangles, i.e. ' &
                   //str(84_int64 + 50_int64*n_announced)//' bytes, but the file has '//str(len(text))//' bytes')
    else
      call err%set(ERR_MESH, "mesh file '"//path//"' is not a valid STL file: shorter than a binary header (" &
                   //str(len(text))//" bytes) and it does not begin with 'solid'")
    end if
  end subroutine parse_stl

  !> 80-byte header, uint32 count, then per triangle 12 little-endian float32 (normal,
  !> 3 vertices) and a uint16 attribute. The stored normal is ignored: orientation comes
  !> from the vertex order, checked by mesh_topology.
  subroutine parse_stl_binary(text, path, n_triangles, s, err)
    character(len=*), intent(in) :: text, path
    integer, intent(in) :: n_triangles
    type(soup_t), intent(out) :: s
    type(error_t), intent(inout) :: err
    character(len=4) :: probe
    real(real32) :: v(9)
    integer :: t, o

    probe = transfer(1_int32, probe)
    if (probe(1:1) /= achar(1)) then
      call err%set(ERR_IO, "mesh file '"//path//"': binary STL (little-endian) cannot be read on this " &
                   //'big-endian machine')
      return
    end if
    if (n_triangles == 0) then
      call err%set(ERR_MESH, "mesh file '"//path//"': binary STL with no triangles")
      return
    end if
    allocate (s%verts(3, 3*n_triangles), s%tris(3, n_triangles))
    do t = 1, n_triangles
      o = 84 + 50*(t - 1) + 12
      v = transfer(text(o + 1:o + 36), v)
      if (.not. all(ieee_is_finite(v))) then
        call err%set(ERR_MESH, "mesh file '"//path//"': binary STL triangle "//str(t) &
                     //' has a coordinate that is not a finite number')
        return
      end if
      s%verts(:, 3*t - 2:3*t) = reshape(real(v, dp), [3, 3])
      s%tris(:, t) = [3*t - 2, 3*t - 1, 3*t]
    end do
    s%nv = 3*n_triangles
    s%nt = n_triangles
  end subroutine parse_stl_binary

  !> solid name / facet normal nx ny nz / outer loop / vertex x y z (3 times) / endloop /
  !> endfacet ... / endsolid name; several solids in one file are read as one mesh.
  !> Keywords are case-insensitive; the file is read as a stream of tokens.
  subroutine parse_stl_ascii(text, path, s, err)
    character(len=*), intent(in) :: text, path
    type(soup_t), intent(out) :: s
    type(error_t), intent(inout) :: err
    integer :: pos, line_no, t1, t2, k, j, n_solids
    real(dp) :: corners(3, 3)
    logical :: ok

    call soup_reserve(s, 3072, 1024)
    pos = 1
    line_no = 1
    n_solids = 0
    solids: do
      call next_stream_token(text, pos, line_no, t1, t2)
      if (t1 > t2) exit solids
      if (lower(text(t1:t2)) /= 'solid') then
        call syntax_error("expected 'solid'")
        return
      end if
      n_solids = n_solids + 1
      call skip_rest_of_line(text, pos)   ! the solid's name may contain spaces
      facets: do
        call next_stream_token(text, pos, line_no, t1, t2)
        if (t1 > t2) then
          call err%set(ERR_MESH, "mesh file '"//path//"', line "//str(line_no) &
                       //": file ends inside a solid (missing 'endsolid'; truncated file?)")
          return
        end if
        if (lower(text(t1:t2)) == 'endsolid') then
          call skip_rest_of_line(text, pos)
          exit facets
        end if
        if (lower(text(t1:t2)) /= 'facet') then
          call syntax_error("expected 'facet' or 'endsolid'")
          return
        end if
        if (.not. keyword('normal')) return
        ! The stored normal is not used (orientation comes from the vertex order), and some
        ! exporters write nan for degenerate facets: its three tokens are skipped unread.
        do k = 1, 3
          call next_stream_token(text, pos, line_no, t1, t2)
        end do
        if (.not. keyword('outer')) return
        if (.not. keyword('loop')) return
        do j = 1, 3
          if (.not. keyword('vertex')) return
          if (.not. numbers(corners(:, j))) return
        end do
        if (.not. keyword('endloop')) return
        if (.not. keyword('endfacet')) return
        do j = 1, 3
          call soup_add_vertex(s, corners(:, j))
        end do
        call soup_add_triangle(s, [s%nv - 2, s%nv - 1, s%nv], line_no)
      end do facets
    end do solids
    if (n_solids == 0) then
      call err%set(ERR_MESH, "mesh file '"//path//"': ASCII STL without any 'solid'")
    end if

  contains

    subroutine syntax_error(expected)
      character(len=*), intent(in) :: expected
      if (t1 > t2) then
        call err%set(ERR_MESH, "mesh file '"//path//"', line "//str(line_no)//': '//expected//', found the end of the file')
      else
        call err%set(ERR_MESH, "mesh file '"//path//"', line "//str(line_no)//': '//expected//", found '" &
                     //text(t1:min(t2, t1 + 40))//"'")
      end if
    end subroutine syntax_error

    logical function keyword(word)
      character(len=*), intent(in) :: word
      call next_stream_token(text, pos, line_no, t1, t2)
      keyword = t1 <= t2
      if (keyword) keyword = lower(text(t1:t2)) == word
      if (.not. keyword) call syntax_error("expected '"//word//"'")
    end function keyword

    logical function numbers(values)
      real(dp), intent(out) :: values(3)
      numbers = .false.
      do k = 1, 3
        call next_stream_token(text, pos, line_no, t1, t2)
        if (t1 > t2) then
          call syntax_error('expected a number')
          return
        end if
        call parse_real(text(t1:t2), values(k), ok)
        if (.not. ok) then
          call syntax_error('expected a number')
          return
        end if
      end do
      numbers = .true.
    end function numbers

  end subroutine parse_stl_ascii

  ! ---------------------------------------------------------------------------------------
  ! OFF
  ! ---------------------------------------------------------------------------------------

  !> OFF (also COFF, NOFF, CNOFF, ST...: per-vertex extras after x y z are ignored), then
  !> "n_vertices n_faces [n_edges]" (on the header line or the next), the vertices, and
  !> faces "n i1 ... in" with 0-based indices, fan-triangulated. '#' starts a comment.
  subroutine parse_off(text, path, s, err)
    character(len=*), intent(in) :: text, path
    type(soup_t), intent(out) :: s
    type(error_t), intent(inout) :: err
    integer :: pos, first, last, line_no, p, t1, t2, k, n_vertices, n_faces, i, n_corners, idx
    integer, allocatable :: poly(:)
    real(dp) :: xyz(3)
    logical :: ok, found
    character(len=:), allocatable :: header

    pos = 1
    line_no = 0
    call next_content_line(found)
    if (.not. found) then
      call err%set(ERR_MESH, "mesh file '"//path//"': no OFF header (the file holds only blanks or comments)")
      return
    end if
    p = 1
    call next_token(text(first:last), p, t1, t2)
    header = text(first + t1 - 1:first + t2 - 1)
    select case (header)
    case ('OFF', 'COFF', 'NOFF', 'CNOFF', 'STOFF', 'STCOFF', 'STNOFF', 'STCNOFF')
      continue
    case default
      call err%set(ERR_MESH, "mesh file '"//path//"', line "//str(line_no)//": expected the header 'OFF', found '" &
                   //header//"'")
      return
    end select
    ! Counts: on the header line after the keyword, or on the next content line.
    call next_token(text(first:last), p, t1, t2)
    found = t1 <= t2
    if (found) found = text(first + t1 - 1:first + t1 - 1) /= '#'
    if (.not. found) then
      call next_content_line(found)
      if (.not. found) then
        call err%set(ERR_MESH, "mesh file '"//path//"': ends before the counts line 'n_vertices n_faces n_edges'")
        return
      end if
      p = 1
      call next_token(text(first:last), p, t1, t2)
    end if
    call parse_int(text(first + t1 - 1:first + t2 - 1), n_vertices, ok)
    if (ok) then
      call next_token(text(first:last), p, t1, t2)
      call parse_int(text(first + t1 - 1:first + t2 - 1), n_faces, ok)
    end if
    if (.not. ok .or. n_vertices < 0 .or. n_faces < 0) then
      call err%set(ERR_MESH, "mesh file '"//path//"', line "//str(line_no) &
                   //": expected the counts 'n_vertices n_faces [n_edges]' as non-negative integers")
      return
    end if

    call soup_reserve(s, max(n_vertices, 1), max(2*n_faces, 1))
    do i = 1, n_vertices
      call next_content_line(found)
      if (.not. found) then
        call err%set(ERR_MESH, "mesh file '"//path//"': ends after "//str(i - 1)//' of the '//str(n_vertices) &
                     //' vertices announced on the counts line')
        return
      end if
      p = 1
      do k = 1, 3
        call next_token(text(first:last), p, t1, t2)
        ok = t1 <= t2
        if (ok) call parse_real(text(first + t1 - 1:first + t2 - 1), xyz(k), ok)
        if (.not. ok) then
          call err%set(ERR_MESH, "mesh file '"//path//"', line "//str(line_no)//': vertex '//str(i - 1) &
                       //' (0-based) needs 3 numeric coordinates')
          return
        end if
      end do
      call soup_add_vertex(s, xyz)
    end do

    allocate (poly(16))
    do i = 1, n_faces
      call next_content_line(found)
      if (.not. found) then
        call err%set(ERR_MESH, "mesh file '"//path//"': ends after "//str(i - 1)//' of the '//str(n_faces) &
                     //' faces announced on the counts line')
        return
      end if
      p = 1
      call next_token(text(first:last), p, t1, t2)
      call parse_int(text(first + t1 - 1:first + t2 - 1), n_corners, ok)
      if (.not. ok .or. n_corners < 3) then
        call err%set(ERR_MESH, "mesh file '"//path//"', line "//str(line_no) &
                     //': a face must start with its number of vertices (at least 3)')
        return
      end if
      if (n_corners > size(poly)) then
        deallocate (poly)
        allocate (poly(n_corners))
      end if
      do k = 1, n_corners
        call next_token(text(first:last), p, t1, t2)
        ok = t1 <= t2
        if (ok) call parse_int(text(first + t1 - 1:first + t2 - 1), idx, ok)
        if (.not. ok) then
          call err%set(ERR_MESH, "mesh file '"//path//"', line "//str(line_no)//': face announces ' &
                       //str(n_corners)//' vertices but vertex '//str(k)//' is missing or not an integer')
          return
        end if
        if (idx < 0 .or. idx >= n_vertices) then
          call err%set(ERR_MESH, "mesh file '"//path//"', line "//str(line_no)//': face refers to vertex ' &
                       //str(idx)//' but the valid (0-based) indices are 0 to '//str(n_vertices - 1))
          return
        end if
        poly(k) = idx + 1
      end do
      do k = 2, n_corners - 1
        call soup_add_triangle(s, [poly(1), poly(k), poly(k + 1)], line_no)
      end do
    end do
    call next_content_line(found)
    if (found) then
      call err%set(ERR_MESH, "mesh file '"//path//"', line "//str(line_no)//': data after the last of the ' &
                   //str(n_faces)//' faces announced on the counts line')
    end if

  contains

    !> Next line that holds something other than blanks and a comment.
    subroutine next_content_line(found)
      logical, intent(out) :: found
      integer :: q
      found = .false.
      do while (pos <= len(text))
        call next_line(text, pos, first, last)
        line_no = line_no + 1
        if (last < first) cycle
        q = verify(text(first:last), ' '//achar(9))
        if (q == 0) cycle
        if (text(first + q - 1:first + q - 1) == '#') cycle
        found = .true.
        return
      end do
    end subroutine next_content_line

  end subroutine parse_off

  ! ---------------------------------------------------------------------------------------
  ! Soup to mesh: scale (done by the caller), weld, drop degenerate triangles, topology.
  ! ---------------------------------------------------------------------------------------

  subroutine soup_to_mesh(s, path, m, info, err)
    type(soup_t), intent(in) :: s
    character(len=*), intent(in) :: path
    type(mesh_t), intent(inout) :: m
    type(mesh_read_stats_t), intent(out) :: info
    type(error_t), intent(inout) :: err
    logical, allocatable :: referenced(:)
    integer, allocatable :: node_of(:), faces(:, :), file_triangle(:)
    real(dp) :: lower(3), upper(3), diag, area_min, e1(3), e2(3), c(3), clock, point(3)
    integer :: t, i, n_kept, n_faces, n_referenced, abc(3), pair(2)
    integer(i8) :: n_crossing
    type(self_intersection_stats_t) :: cross_stats

    info%n_file_vertices = s%nv
    info%n_file_triangles = s%nt
    if (s%nt == 0) then
      call err%set(ERR_MESH, "mesh file '"//path//"' has no faces (a solid needs a closed triangle surface)")
      return
    end if
    ! Bounds of the vertices that faces use: stray unused vertices must not loosen the
    ! welding tolerance.
    allocate (referenced(s%nv))
    referenced = .false.
    do t = 1, s%nt
      referenced(s%tris(:, t)) = .true.
    end do
    lower = huge(1.0_dp)
    upper = -huge(1.0_dp)
    do i = 1, s%nv
      if (referenced(i)) then
        lower = min(lower, s%verts(:, i))
        upper = max(upper, s%verts(:, i))
      end if
    end do
    diag = norm2(upper - lower)
    n_referenced = count(referenced)
    clock = wall_seconds()

    allocate (node_of(s%nv))
    call weld(s%verts(:, 1:s%nv), referenced, lower, weld_tolerance*diag, node_of, n_kept)
    info%n_merged_vertices = n_referenced - n_kept

    ! Degenerate triangles: a repeated node (after welding) or an area below the tolerance.
    area_min = degenerate_area_tolerance*diag**2
    allocate (faces(3, s%nt), file_triangle(s%nt))
    n_faces = 0
    do t = 1, s%nt
      abc = node_of(s%tris(:, t))
      if (abc(1) == abc(2) .or. abc(2) == abc(3) .or. abc(3) == abc(1)) cycle
      e1 = s%verts(:, abc(2)) - s%verts(:, abc(1))
      e2 = s%verts(:, abc(3)) - s%verts(:, abc(1))
      c = [e1(2)*e2(3) - e1(3)*e2(2), e1(3)*e2(1) - e1(1)*e2(3), e1(1)*e2(2) - e1(2)*e2(1)]
      if (0.5_dp*norm2(c) < area_min) cycle
      n_faces = n_faces + 1
      faces(:, n_faces) = abc
      file_triangle(n_faces) = t
    end do
    deallocate (node_of)
    info%n_degenerate_triangles = s%nt - n_faces
    if (n_faces == 0) then
      call err%set(ERR_MESH, "mesh file '"//path//"': all "//str(s%nt)//' triangles are degenerate (no area)')
      return
    end if

    ! All file vertices go in; the merged and unused ones are dropped by mesh_topology.
    call m%init(s%verts(:, 1:s%nv), faces(:, 1:n_faces), path)
    deallocate (faces)
    info%seconds_weld = wall_seconds() - clock
    clock = wall_seconds()
    call build_mesh_topology(m, err)
    info%seconds_topology = wall_seconds() - clock
    if (err%failed()) return
    info%n_unused_nodes = s%nv - info%n_merged_vertices - m%n_nodes

    ! A closed, oriented surface may still cross itself; then it bounds no solid.
    clock = wall_seconds()
    call find_self_intersections(m, self_intersection_tolerance*diag, n_crossing, pair, point, cross_stats)
    info%seconds_self_intersection = wall_seconds() - clock
    info%n_pair_tests = cross_stats%n_pair_tests
    if (n_crossing > 0) then
      call err%set(ERR_MESH, "mesh '"//path//"' intersects itself (a solid's surface must not cross itself): " &
                   //str(n_crossing)//' pair(s) of faces cross, first: '//triangle_text(pair(1))//' and ' &
                   //triangle_text(pair(2))//' cross at '//point_text(point))
    end if

  contains

    !> "triangle 12 (line 40)": counted from 1 in file order, polygons split into fans.
    function triangle_text(face) result(text)
      integer, intent(in) :: face
      character(len=:), allocatable :: text
      integer :: k
      k = file_triangle(face)
      text = 'triangle '//str(k)
      if (allocated(s%tri_line)) text = text//' (line '//str(s%tri_line(k))//')'
    end function triangle_text

  end subroutine soup_to_mesh

  function point_text(p) result(text)
    real(dp), intent(in) :: p(3)
    character(len=:), allocatable :: text
    text = '('//str(p(1), '(1pg0.9)')//', '//str(p(2), '(1pg0.9)')//', '//str(p(3), '(1pg0.9)')//')'
  end function point_text

  !> Wall-clock time [s] since an arbitrary origin, for the stage timings.
  real(dp) function wall_seconds()
    integer(int64) :: count, rate
    call system_clock(count, rate)
    wall_seconds = real(count, dp)/real(rate, dp)
  end function wall_seconds

  !> Merges vertices closer than tol [file units] (exact duplicates always): node_of(i) is
  !> the index of the first vertex within tol of vertex i, itself for the first of its
  !> cluster. Node numbers thus stay the file's vertex numbers (messages can be checked
  !> against the file); merged and unreferenced vertices become unused nodes, which
  !> mesh_topology drops. A spatial hash on cells of size 2 tol: a kept vertex within tol
  !> of p lies in p's cell or, along each axis, the neighbour on the side of the cell
  !> half p is in, so 8 cells are searched (not 27). Each vertex joins the first kept
  !> vertex found within tol (greedy: a chain of vertices each within tol of the next is
  !> not merged end to end). Unreferenced vertices get 0 and are not hashed.
  subroutine weld(verts, referenced, lower, tol, node_of, n_kept)
    real(dp), intent(in) :: verts(:, :), lower(3), tol
    logical, intent(in) :: referenced(:)
    integer, intent(out) :: node_of(:)
    integer, intent(out) :: n_kept
    integer, allocatable :: head(:), next(:)
    integer(int64) :: cell(3), mask, table_size, slot, side(3)
    integer :: i, r, found, dx, dy, dz, nv
    real(dp) :: p(3), q(3), tol2, cell_size

    nv = size(verts, 2)
    node_of = 0
    n_kept = 0
    if (tol <= 0.0_dp) then
      ! All referenced vertices coincide (zero bounding box): they are one node.
      do i = 1, nv
        if (.not. referenced(i)) cycle
        if (n_kept == 0) then
          n_kept = 1
          found = i
        end if
        node_of(i) = found
      end do
      return
    end if
    table_size = 1024
    do while (table_size < 2_int64*nv)
      table_size = 2*table_size
    end do
    mask = table_size - 1
    allocate (head(0:table_size - 1), next(nv))
    head = 0
    tol2 = tol*tol
    cell_size = 2.0_dp*tol
    do i = 1, nv
      if (.not. referenced(i)) cycle
      p = verts(:, i)
      ! Cell indices stay below 1/(2 weld_tolerance) ~ 5e8 < 2^31: no overflow in the hash.
      q = (p - lower)/cell_size
      cell = floor(q, kind=int64)
      side = merge(-1_int64, 1_int64, q - real(cell, dp) < 0.5_dp)
      found = 0
      search: do dz = 0, 1
        do dy = 0, 1
          do dx = 0, 1
            r = head(cell_hash(cell + [dx, dy, dz]*side, mask))
            do while (r /= 0)
              if (sum((verts(:, r) - p)**2) <= tol2) then
                found = r
                exit search
              end if
              r = next(r)
            end do
          end do
        end do
      end do search
      if (found == 0) then
        n_kept = n_kept + 1
        slot = cell_hash(cell, mask)
        next(i) = head(slot)
        head(slot) = i
        found = i
      end if
      node_of(i) = found
    end do
  end subroutine weld

  pure integer(int64) function cell_hash(cell, mask)
    integer(int64), intent(in) :: cell(3), mask
    ! Large odd multipliers spread neighbouring cells; |cell| < 2^31 and the multipliers
    ! are < 2^27, so the products stay far below 2^63.
    cell_hash = iand(ieor(ieor(cell(1)*73856093_int64, cell(2)*19349663_int64), cell(3)*83492791_int64), mask)
  end function cell_hash

  ! ---------------------------------------------------------------------------------------
  ! Soup storage
  ! ---------------------------------------------------------------------------------------

  subroutine soup_reserve(s, n_vertices, n_triangles)
    type(soup_t), intent(inout) :: s
    integer, intent(in) :: n_vertices, n_triangles
    allocate (s%verts(3, n_vertices), s%tris(3, n_triangles), s%tri_line(n_triangles))
    s%nv = 0
    s%nt = 0
  end subroutine soup_reserve

  subroutine soup_add_vertex(s, p)
    type(soup_t), intent(inout) :: s
    real(dp), intent(in) :: p(3)
    real(dp), allocatable :: grown(:, :)
    if (s%nv == size(s%verts, 2)) then
      allocate (grown(3, 2*size(s%verts, 2)))
      grown(:, 1:s%nv) = s%verts(:, 1:s%nv)
      call move_alloc(grown, s%verts)
    end if
    s%nv = s%nv + 1
    s%verts(:, s%nv) = p
  end subroutine soup_add_vertex

  subroutine soup_add_triangle(s, abc, line)
    type(soup_t), intent(inout) :: s
    integer, intent(in) :: abc(3), line
    integer, allocatable :: grown(:, :), grown_line(:)
    if (s%nt == size(s%tris, 2)) then
      allocate (grown(3, 2*size(s%tris, 2)), grown_line(2*size(s%tris, 2)))
      grown(:, 1:s%nt) = s%tris(:, 1:s%nt)
      grown_line(1:s%nt) = s%tri_line(1:s%nt)
      call move_alloc(grown, s%tris)
      call move_alloc(grown_line, s%tri_line)
    end if
    s%nt = s%nt + 1
    s%tris(:, s%nt) = abc
    s%tri_line(s%nt) = line
  end subroutine soup_add_triangle

  ! ---------------------------------------------------------------------------------------
  ! Text scanning
  ! ---------------------------------------------------------------------------------------

  !> The line starting at pos is text(first:last) without its LF or CR LF; pos moves to
  !> the start of the next line.
  pure subroutine next_line(text, pos, first, last)
    character(len=*), intent(in) :: text
    integer, intent(inout) :: pos
    integer, intent(out) :: first, last
    integer :: k
    first = pos
    k = index(text(pos:), achar(10))
    if (k == 0) then
      last = len(text)
      pos = len(text) + 1
    else
      last = pos + k - 2
      pos = pos + k
    end if
    if (last >= first) then
      if (text(last:last) == achar(13)) last = last - 1
    end if
  end subroutine next_line

  !> Next blank-separated token of line from position pos: line(t1:t2), empty if t1 > t2.
  pure subroutine next_token(line, pos, t1, t2)
    character(len=*), intent(in) :: line
    integer, intent(inout) :: pos
    integer, intent(out) :: t1, t2
    do while (pos <= len(line))
      if (iachar(line(pos:pos)) > 32) exit
      pos = pos + 1
    end do
    t1 = pos
    do while (pos <= len(line))
      if (iachar(line(pos:pos)) <= 32) exit
      pos = pos + 1
    end do
    t2 = pos - 1
  end subroutine next_token

  !> Like next_token over the whole text, counting the line feeds it skips.
  pure subroutine next_stream_token(text, pos, line_no, t1, t2)
    character(len=*), intent(in) :: text
    integer, intent(inout) :: pos, line_no
    integer, intent(out) :: t1, t2
    do while (pos <= len(text))
      if (iachar(text(pos:pos)) > 32) exit
      if (text(pos:pos) == achar(10)) line_no = line_no + 1
      pos = pos + 1
    end do
    t1 = pos
    do while (pos <= len(text))
      if (iachar(text(pos:pos)) <= 32) exit
      pos = pos + 1
    end do
    t2 = pos - 1
  end subroutine next_stream_token

  !> Moves pos to the line feed that ends the current line (counted by the next token read).
  pure subroutine skip_rest_of_line(text, pos)
    character(len=*), intent(in) :: text
    integer, intent(inout) :: pos
    integer :: k
    if (pos > len(text)) return
    k = index(text(pos:), achar(10))
    if (k == 0) then
      pos = len(text) + 1
    else
      pos = pos + k - 1
    end if
  end subroutine skip_rest_of_line

  !> Decimal integer with optional sign, the whole token.
  pure subroutine parse_int(token, value, ok)
    character(len=*), intent(in) :: token
    integer, intent(out) :: value
    logical, intent(out) :: ok
    integer(int64) :: v
    integer :: i, start
    value = 0
    ok = .false.
    start = 1
    if (len(token) == 0) return
    if (token(1:1) == '-' .or. token(1:1) == '+') start = 2
    if (start > len(token)) return
    v = 0
    do i = start, len(token)
      if (token(i:i) < '0' .or. token(i:i) > '9') return
      v = 10*v + (iachar(token(i:i)) - iachar('0'))
      if (v > huge(value)) return
    end do
    if (token(1:1) == '-') v = -v
    value = int(v)
    ok = .true.
  end subroutine parse_int

  !> Decimal real [sign] digits [. digits] [e|E|d|D [sign] digits], the whole token;
  !> rejects nan, inf and overflow. Up to 15-16 significant digits and a decimal exponent
  !> within +-22 (every coordinate of the test meshes) are converted exactly by one
  !> correctly rounded multiplication or division; other numbers, already checked for
  !> syntax, go through the compiler's (correctly rounded) internal read.
  subroutine parse_real(token, value, ok)
    character(len=*), intent(in) :: token
    real(dp), intent(out) :: value
    logical, intent(out) :: ok
    integer(int64), parameter :: exact_limit = 2_int64**53
    integer(int64) :: mantissa
    integer :: i, n, exponent, exp_digits, exp_sign, power, n_digits, digit, ios
    logical :: negative, exact, after_point

    value = 0.0_dp
    ok = .false.
    n = len(token)
    if (n == 0) return
    i = 1
    negative = token(1:1) == '-'
    if (token(1:1) == '-' .or. token(1:1) == '+') i = 2
    mantissa = 0
    power = 0
    n_digits = 0
    exact = .true.
    after_point = .false.
    do while (i <= n)
      if (token(i:i) == '.') then
        if (after_point) return
        after_point = .true.
      else if (token(i:i) >= '0' .and. token(i:i) <= '9') then
        n_digits = n_digits + 1
        digit = iachar(token(i:i)) - iachar('0')
        if (exact) then
          if (mantissa > (exact_limit - digit)/10) then
            exact = .false.
          else
            mantissa = 10*mantissa + digit
            if (after_point) power = power - 1
          end if
        end if
      else
        exit
      end if
      i = i + 1
    end do
    if (n_digits == 0) return
    exponent = 0
    if (i <= n) then
      if (scan(token(i:i), 'eEdD') == 0) return
      i = i + 1
      exp_sign = 1
      if (i <= n) then
        if (token(i:i) == '-' .or. token(i:i) == '+') then
          if (token(i:i) == '-') exp_sign = -1
          i = i + 1
        end if
      end if
      exp_digits = 0
      do while (i <= n)
        if (token(i:i) < '0' .or. token(i:i) > '9') return
        if (exponent < 100000) exponent = 10*exponent + (iachar(token(i:i)) - iachar('0'))
        exp_digits = exp_digits + 1
        i = i + 1
      end do
      if (exp_digits == 0) return
      exponent = exp_sign*exponent
    end if
    power = power + exponent
    if (exact .and. mantissa == 0) then
      value = 0.0_dp
    else if (exact .and. abs(power) <= 22) then
      if (power >= 0) then
        value = real(mantissa, dp)*exact_powers_of_ten(power)
      else
        value = real(mantissa, dp)/exact_powers_of_ten(-power)
      end if
      if (negative) value = -value
    else
      read (token, *, iostat=ios) value
      if (ios /= 0) return
    end if
    ok = ieee_is_finite(value)
  end subroutine parse_real

end module mesh_io
