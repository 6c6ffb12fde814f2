!> Output frames for ParaView (docs/output.md): every call of write makes one HDF5 file
!> dir/frames/frame_NNNNNN.h5 (bodies and their world surfaces at one time) with parallel
!> HDF5, each rank writing its owned rows at its offset, then rewrites the two XDMF indexes
!> dir/surfaces.xmf and dir/bodies.xmf, each one temporal collection of all frames so far.
!>
!> Cost: the frames are listed in blocks of block_frames. A block's grids are written once,
!> into dir/frames/{surfaces,bodies}_block_NNNNNN.xmf, when its last frame is written; the
!> indexes include the finished blocks (XInclude, which ParaView's XDMF reader resolves) and
!> list the frames of the open block themselves. Rewriting an index after a frame then costs
!> n/block_frames short lines plus at most block_frames grids, not n grids: a run of 2,000
!> frames spent 26 ms per frame rewriting full indexes.
!>
!> Crash safety: a frame is written under a temporary name and renamed once complete, and the
!> block files and the XDMF indexes are replaced by rename after what they list exists, so a
!> run that stops at any point leaves every frame the XDMF files list complete and readable.
module frame_writer
  use kinds, only: dp, i8
  use constants, only: name_length
  use error_status, only: error_t, ERR_IO, ERR_INTERNAL
  use string_utils, only: str, join_path
  use parallel_env, only: parallel_t
  use body_state, only: bodies_t
  use shape, only: shape_library_t
  use quaternion, only: quat_mul, quat_conj
  use file_system, only: make_directory, rename_file, remove_file, write_file_atomically
  use surface_render, only: surface_render_t
  use h5_utils, only: hid_t, h5u_start, h5u_create_parallel, h5u_open_serial, h5u_close_file, &
                      h5u_create_group, h5u_close_group, h5u_write, h5u_write_strings, h5u_write_attr, &
                      h5u_read_attr
  implicit none
  private
  public :: frame_writer_t, frame_format, frame_version, frame_file_name

  character(len=*), parameter :: frame_format = 'ricochet-frame'   !< root attribute 'format'
  integer, parameter :: frame_version = 1
  integer(i8), parameter :: unknown_size = -1   !< sizes of restored frames until read back

  type :: frame_writer_t
    character(len=:), allocatable :: dir         !< output folder; frames in dir/frames/
    integer :: n_frames = 0                      !< frames written (or restored) so far
    real(dp), allocatable :: frame_times(:)      !< (capacity) times of frames 1..n_frames [s]
    !> Sizes of each frame (bodies, surface points, triangles): the XDMF index needs them
    !> (-1 for restored frames until their files are read back; rank 0 only).
    integer(i8), allocatable :: frame_sizes(:, :)   !< (3, capacity)
    integer :: block_frames = 32                 !< frames per block file of the indexes (0: none)
    integer :: n_blocks_written = 0              !< blocks whose files this writer has written
    type(surface_render_t) :: render
  contains
    procedure :: init => frame_init
    procedure :: write => frame_write
    procedure :: restore => frame_restore
    procedure :: free => frame_free
  end type frame_writer_t

  !> The text of an XDMF file as it is built (put), before it is written.
  type :: text_t
    character(len=:), allocatable :: text
    integer :: length = 0
  end type text_t

contains

  !> Relative path of frame number index (0-based) from the output folder.
  pure function frame_file_name(index) result(name)
    integer, intent(in) :: index
    character(len=:), allocatable :: name
    character(len=32) :: buffer
    write (buffer, '(a,i6.6,a)') 'frames/frame_', index, '.h5'
    name = trim(buffer)
  end function frame_file_name

  !> Prepares writing into dir (created with dir/frames/ if missing, by rank 0). Collective.
  subroutine frame_init(self, par, dir, err)
    class(frame_writer_t), intent(inout) :: self
    type(parallel_t), intent(in) :: par
    character(len=*), intent(in) :: dir
    type(error_t), intent(inout) :: err
    call self%free()
    self%dir = trim(dir)
    allocate (self%frame_times(16), self%frame_sizes(3, 16))
    self%frame_times = 0.0_dp
    self%frame_sizes = unknown_size
    call self%render%init()
    if (par%is_root()) call make_directory(join_path(self%dir, 'frames'), err)
    call agree(par, err, "output folder '"//self%dir//"': failed on rank 0")
    if (err%ok()) call h5u_start(err)
  end subroutine frame_init

  subroutine frame_free(self)
    class(frame_writer_t), intent(inout) :: self
    if (allocated(self%dir)) deallocate (self%dir)
    if (allocated(self%frame_times)) deallocate (self%frame_times)
    if (allocated(self%frame_sizes)) deallocate (self%frame_sizes)
    self%n_frames = 0
    self%n_blocks_written = 0
  end subroutine frame_free

  !> Continues after a restart: frames 1..n_frames (times from the checkpoint) count as
  !> written; later frame files are overwritten as the run goes on. Local, no I/O: the sizes
  !> of the restored frames, which the XDMF indexes need, are read back from their files
  !> (on rank 0) when the next frame is written, which then rewrites the block files of the
  !> restored frames (a block file on disk may come from frames after the checkpoint) and
  !> the indexes.
  subroutine frame_restore(self, n_frames, frame_times)
    class(frame_writer_t), intent(inout) :: self
    integer, intent(in) :: n_frames
    real(dp), intent(in) :: frame_times(:)
    integer :: n
    n = max(0, min(n_frames, size(frame_times)))
    call ensure_capacity(self, max(n, 1))
    self%n_frames = n
    self%frame_times(1:n) = frame_times(1:n)
    self%frame_sizes = unknown_size
    self%n_blocks_written = 0
  end subroutine frame_restore

  !> Reads the sizes of restored frames back from their files (rank 0).
  subroutine resolve_sizes(self, err)
    type(frame_writer_t), intent(inout) :: self
    type(error_t), intent(inout) :: err
    integer(hid_t) :: file_id
    integer :: i
    character(len=:), allocatable :: path
    if (all(self%frame_sizes(1, 1:self%n_frames) /= unknown_size)) return
    do i = 1, self%n_frames
      if (self%frame_sizes(1, i) /= unknown_size) cycle
      path = join_path(self%dir, frame_file_name(i - 1))
      call h5u_open_serial(path, file_id, err)
      call h5u_read_attr(file_id, 'n_bodies', self%frame_sizes(1, i), err)
      call h5u_read_attr(file_id, 'n_points', self%frame_sizes(2, i), err)
      call h5u_read_attr(file_id, 'n_triangles', self%frame_sizes(3, i), err)
      call h5u_close_file(file_id, err)
      if (err%failed()) then
        call err%prefix("restart: frame file '"//path//"', written before the checkpoint: ")
        exit
      end if
    end do
  end subroutine resolve_sizes

  !> Writes frame number n_frames (0-based) at `time` [s]: all owned bodies of every rank
  !> and their surfaces; then the XDMF indexes. Collective.
  subroutine frame_write(self, par, time, bodies, shapes, group_names, err)
    class(frame_writer_t), intent(inout) :: self
    type(parallel_t), intent(in) :: par
    real(dp), intent(in) :: time
    type(bodies_t), intent(in) :: bodies
    type(shape_library_t), intent(in) :: shapes
    character(len=*), intent(in) :: group_names(:)
    type(error_t), intent(inout) :: err
    integer(i8) :: n_local, n_bodies, body_offset, np_local, nt_local, n_points, n_triangles, &
                   point_offset, triangle_offset
    integer(hid_t) :: file_id, group_id
    real(dp), allocatable :: position(:, :), orientation(:, :), points(:, :), velocity(:, :)
    integer(i8), allocatable :: triangles(:, :), body_id(:), vertex(:)
    character(len=name_length), allocatable :: names(:)
    character(len=:), allocatable :: final_path, temporary
    integer :: i, n
    if (err%failed()) return
    if (.not. allocated(self%dir)) then
      call err%set(ERR_IO, 'frame writer used before init')
      return
    end if

    n = bodies%n_owned
    if (n > 0) then
      if (any(bodies%shape_id(1:n) < 1 .or. bodies%shape_id(1:n) > shapes%n_shapes)) then
        call err%set(ERR_INTERNAL, 'frame output: a body refers to a shape that is not in the library')
      end if
    end if
    call agree(par, err, 'frame output: bad shape index on another rank')
    if (err%failed()) return

    ! Row ranges of this rank in the global datasets.
    n_local = n
    n_bodies = par%sum(n_local)
    body_offset = par%exscan(n_local)
    call self%render%count(bodies, shapes, np_local, nt_local)
    n_points = par%sum(np_local)
    n_triangles = par%sum(nt_local)
    point_offset = par%exscan(np_local)
    triangle_offset = par%exscan(nt_local)

    allocate (position(3, n), orientation(4, n), names(n), vertex(n))
    do i = 1, n
      position(:, i) = bodies%x(:, i)
      ! Users see their shape's own frame: q_user = q (x) conj(q_principal).
      orientation(:, i) = quat_mul(bodies%q(:, i), quat_conj(shapes%shapes(bodies%shape_id(i))%q_principal))
      names(i) = ''
      if (bodies%group_id(i) >= 1 .and. bodies%group_id(i) <= size(group_names)) names(i) = group_names(bodies%group_id(i))
      vertex(i) = body_offset + i - 1
    end do
    allocate (points(3, np_local), velocity(3, np_local), triangles(3, nt_local), body_id(nt_local))
    call self%render%build(bodies, shapes, point_offset, points, triangles, body_id, velocity)

    final_path = join_path(self%dir, frame_file_name(self%n_frames))
    temporary = final_path//'.tmp'
    call h5u_create_parallel(par, temporary, file_id, err)
    call h5u_write_attr(file_id, 'format', frame_format, err)
    call h5u_write_attr(file_id, 'version', frame_version, err)
    call h5u_write_attr(file_id, 'time', time, err)
    call h5u_write_attr(file_id, 'frame', self%n_frames, err)
    call h5u_write_attr(file_id, 'n_bodies', n_bodies, err)
    call h5u_write_attr(file_id, 'n_points', n_points, err)
    call h5u_write_attr(file_id, 'n_triangles', n_triangles, err)

    call h5u_create_group(file_id, 'bodies', group_id, err)
    call h5u_write(group_id, 'gid', bodies%gid(1:n), n_bodies, body_offset, err)
    call h5u_write_strings(group_id, 'name', names, n_bodies, body_offset, err)
    call h5u_write(group_id, 'shape_id', bodies%shape_id(1:n), n_bodies, body_offset, err)
    call h5u_write(group_id, 'group_id', bodies%group_id(1:n), n_bodies, body_offset, err)
    call h5u_write(group_id, 'position', position, n_bodies, body_offset, err)
    call h5u_write(group_id, 'orientation', orientation, n_bodies, body_offset, err)
    call h5u_write(group_id, 'velocity', bodies%v(:, 1:n), n_bodies, body_offset, err)
    call h5u_write(group_id, 'angular_velocity', bodies%w(:, 1:n), n_bodies, body_offset, err)
    call h5u_write(group_id, 'vertex', vertex, n_bodies, body_offset, err)
    call h5u_close_group(group_id)

    call h5u_create_group(file_id, 'surface', group_id, err)
    call h5u_write(group_id, 'points', points, n_points, point_offset, err)
    call h5u_write(group_id, 'triangles', triangles, n_triangles, triangle_offset, err)
    call h5u_write(group_id, 'body_id', body_id, n_triangles, triangle_offset, err)
    call h5u_write(group_id, 'velocity', velocity, n_points, point_offset, err)
    call h5u_close_group(group_id)
    call h5u_close_file(file_id, err)
    call agree(par, err, 'writing a frame failed on another rank')
    if (err%failed()) then
      call err%prefix("frame file '"//temporary//"': ")
      call discard(par, temporary)
      return
    end if

    ! Every rank has closed the file: publish it under its final name, then list it.
    call par%barrier()
    call ensure_capacity(self, self%n_frames + 1)
    self%n_frames = self%n_frames + 1
    self%frame_times(self%n_frames) = time
    self%frame_sizes(:, self%n_frames) = [n_bodies, n_points, n_triangles]
    if (par%is_root()) then
      call rename_file(temporary, final_path, err)
      call resolve_sizes(self, err)
      do while (err%ok() .and. self%block_frames > 0 .and. &
                (self%n_blocks_written + 1)*self%block_frames <= self%n_frames)
        call write_block(self, self%n_blocks_written, 'surfaces', err)
        call write_block(self, self%n_blocks_written, 'bodies', err)
        self%n_blocks_written = self%n_blocks_written + 1
      end do
      if (err%ok()) call write_indexes(self, err)
    end if
    call agree(par, err, 'publishing a frame failed on rank 0')
  end subroutine frame_write

  subroutine ensure_capacity(self, n)
    type(frame_writer_t), intent(inout) :: self
    integer, intent(in) :: n
    real(dp), allocatable :: times(:)
    integer(i8), allocatable :: sizes(:, :)
    integer :: capacity
    if (.not. allocated(self%frame_times)) then
      allocate (self%frame_times(max(n, 16)), self%frame_sizes(3, max(n, 16)))
      self%frame_times = 0.0_dp
      self%frame_sizes = unknown_size
      return
    end if
    if (size(self%frame_times) >= n) return
    capacity = max(n, 2*size(self%frame_times))
    allocate (times(capacity), sizes(3, capacity))
    times = 0.0_dp
    sizes = unknown_size
    times(1:self%n_frames) = self%frame_times(1:self%n_frames)
    sizes(:, 1:self%n_frames) = self%frame_sizes(:, 1:self%n_frames)
    call move_alloc(times, self%frame_times)
    call move_alloc(sizes, self%frame_sizes)
  end subroutine ensure_capacity

  !> Rewrites dir/surfaces.xmf and dir/bodies.xmf (rank 0), each through a temporary file.
  subroutine write_indexes(self, err)
    type(frame_writer_t), intent(in) :: self
    type(error_t), intent(inout) :: err
    call write_index(self, 'surfaces', err)
    call write_index(self, 'bodies', err)
  end subroutine write_indexes

  !> Relative path of block number `block` (0-based) of index `kind` from the output folder.
  function block_file_name(kind, block) result(name)
    character(len=*), intent(in) :: kind
    integer, intent(in) :: block
    character(len=:), allocatable :: name
    character(len=16) :: number
    write (number, '(i6.6)') block
    name = 'frames/'//kind//'_block_'//trim(number)//'.xmf'
  end function block_file_name

  !> One XDMF 2 index, dir/<kind>.xmf: a temporal collection with one uniform grid per
  !> frame: the finished blocks by XInclude, then the frames of the open block. Paths to the
  !> HDF5 files are relative to the .xmf (ParaView resolves them from the .xmf's folder,
  !> included grids too).
  subroutine write_index(self, kind, err)
    type(frame_writer_t), intent(in) :: self
    character(len=*), intent(in) :: kind
    type(error_t), intent(inout) :: err
    type(text_t) :: out
    integer :: block, i
    if (err%failed()) return
    call open_xdmf(out, kind, includes=.true.)
    do block = 0, self%n_blocks_written - 1
      call put(out, '   <xi:include href="'//block_file_name(kind, block)// &
        '" xpointer="xpointer(//Xdmf/Domain/Grid/Grid)"/>')
    end do
    do i = self%n_blocks_written*self%block_frames + 1, self%n_frames
      call write_grid(self, out, kind, i)
    end do
    call close_xdmf(out, join_path(self%dir, kind//'.xmf'), err)
  end subroutine write_index

  !> Block number `block` (0-based) of index `kind`: the grids of its block_frames frames, in
  !> an XDMF file of their own that the index includes.
  subroutine write_block(self, block, kind, err)
    type(frame_writer_t), intent(in) :: self
    integer, intent(in) :: block
    character(len=*), intent(in) :: kind
    type(error_t), intent(inout) :: err
    type(text_t) :: out
    integer :: i
    if (err%failed()) return
    call open_xdmf(out, kind//'_block_'//str(block), includes=.false.)
    do i = block*self%block_frames + 1, (block + 1)*self%block_frames
      call write_grid(self, out, kind, i)
    end do
    call close_xdmf(out, join_path(self%dir, block_file_name(kind, block)), err)
  end subroutine write_block

  !> Starts the text of an XDMF 2 file, up to the opening of its temporal collection `name`
  !> (includes: an index, which includes blocks). The text is built in memory and written
  !> in one go by close_xdmf: one place to check the write (a full disk) for every line.
  subroutine open_xdmf(out, name, includes)
    type(text_t), intent(out) :: out
    character(len=*), intent(in) :: name
    logical, intent(in) :: includes
    call put(out, '<?xml version="1.0" ?>')
    if (includes) then
      call put(out, '<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>')
      call put(out, '<Xdmf xmlns:xi="http://www.w3.org/2001/XInclude" Version="2.0">')
    else
      ! No DOCTYPE in a block: libxml2 would look for Xdmf.dtd beside it when including it.
      call put(out, '<Xdmf Version="2.0">')
    end if
    call put(out, ' <Domain>')
    call put(out, '  <Grid Name="'//name//'" GridType="Collection" CollectionType="Temporal">')
  end subroutine open_xdmf

  !> Ends the text open_xdmf started and replaces `path` by it (temporary file, rename). On
  !> a failed write the temporary is removed and `path` keeps its previous content.
  subroutine close_xdmf(out, path, err)
    type(text_t), intent(inout) :: out
    character(len=*), intent(in) :: path
    type(error_t), intent(inout) :: err
    call put(out, '  </Grid>')
    call put(out, ' </Domain>')
    call put(out, '</Xdmf>')
    call write_file_atomically(path, out%text(1:out%length), err)
  end subroutine close_xdmf

  !> Appends one line to the text (capacity doubles: linear cost, the indexes reach ~100 kB).
  subroutine put(out, line)
    type(text_t), intent(inout) :: out
    character(len=*), intent(in) :: line
    character(len=:), allocatable :: grown
    integer :: needed
    needed = out%length + len(line) + 1
    if (.not. allocated(out%text)) allocate (character(len=max(65536, needed)) :: out%text)
    if (len(out%text) < needed) then
      allocate (character(len=max(2*len(out%text), needed)) :: grown)
      grown(1:out%length) = out%text(1:out%length)
      call move_alloc(grown, out%text)
    end if
    out%text(out%length + 1:needed) = line//new_line('a')
    out%length = needed
  end subroutine put

  !> The uniform grid of frame i (1-based) for index `kind` ('surfaces' or 'bodies').
  subroutine write_grid(self, out, kind, i)
    type(frame_writer_t), intent(in) :: self
    type(text_t), intent(inout) :: out
    integer, intent(in) :: i
    character(len=*), intent(in) :: kind
    character(len=:), allocatable :: h5, nb, np, nt
    h5 = frame_file_name(i - 1)
    nb = str(self%frame_sizes(1, i))
    np = str(self%frame_sizes(2, i))
    nt = str(self%frame_sizes(3, i))
    call put(out, '   <Grid Name="frame_'//str(i - 1)//'" GridType="Uniform">')
    call put(out, '    <Time Value="'//real_text(self%frame_times(i))//'"/>')
    if (kind == 'surfaces') then
      call put(out, '    <Topology TopologyType="Triangle" NumberOfElements="'//nt//'">')
      call data_item(out, nt//' 3', 'Int', h5//':/surface/triangles')
      call put(out, '    </Topology>')
      call put(out, '    <Geometry GeometryType="XYZ">')
      call data_item(out, np//' 3', 'Float', h5//':/surface/points')
      call put(out, '    </Geometry>')
      call attribute(out, 'body_id', 'Scalar', 'Cell', nt, 'Int', h5//':/surface/body_id')
      call attribute(out, 'velocity', 'Vector', 'Node', np//' 3', 'Float', h5//':/surface/velocity')
    else
      ! Polyvertex needs explicit connectivity, or ParaView shows no cells.
      call put(out, '    <Topology TopologyType="Polyvertex" NumberOfElements="'//nb// &
        '" NodesPerElement="1">')
      call data_item(out, nb, 'Int', h5//':/bodies/vertex')
      call put(out, '    </Topology>')
      call put(out, '    <Geometry GeometryType="XYZ">')
      call data_item(out, nb//' 3', 'Float', h5//':/bodies/position')
      call put(out, '    </Geometry>')
      call attribute(out, 'gid', 'Scalar', 'Node', nb, 'Int', h5//':/bodies/gid')
      call attribute(out, 'shape_id', 'Scalar', 'Node', nb, 'Int4', h5//':/bodies/shape_id')
      call attribute(out, 'group_id', 'Scalar', 'Node', nb, 'Int4', h5//':/bodies/group_id')
      call attribute(out, 'velocity', 'Vector', 'Node', nb//' 3', 'Float', h5//':/bodies/velocity')
      call attribute(out, 'angular_velocity', 'Vector', 'Node', nb//' 3', 'Float', &
                     h5//':/bodies/angular_velocity')
      ! 'Vector' with 4 columns: VTK's XDMF reader then makes a 4-component array per body
      ! ('Matrix' would give one tuple of 4n values).
      call attribute(out, 'orientation', 'Vector', 'Node', nb//' 4', 'Float', h5//':/bodies/orientation')
    end if
    call put(out, '   </Grid>')
  end subroutine write_grid

  !> number: 'Float' (f64), 'Int' (i64) or 'Int4' (i32), as written by h5_utils.
  subroutine data_item(out, dims, number, source)
    type(text_t), intent(inout) :: out
    character(len=*), intent(in) :: dims, number, source
    character(len=:), allocatable :: type_text
    select case (number)
    case ('Float')
      type_text = 'NumberType="Float" Precision="8"'
    case ('Int4')
      type_text = 'NumberType="Int" Precision="4"'
    case default
      type_text = 'NumberType="Int" Precision="8"'
    end select
    call put(out, '     <DataItem Dimensions="'//dims//'" '//type_text//' Format="HDF">'//source//'</DataItem>')
  end subroutine data_item

  subroutine attribute(out, name, kind, centre, dims, number, source)
    type(text_t), intent(inout) :: out
    character(len=*), intent(in) :: name, kind, centre, dims, number, source
    call put(out, '    <Attribute Name="'//name//'" AttributeType="'//kind//'" Center="'//centre//'">')
    call data_item(out, dims, number, source)
    call put(out, '    </Attribute>')
  end subroutine attribute

  !> 17 significant digits: reads back as the same double (XDMF times match the run exactly).
  function real_text(value) result(text)
    real(dp), intent(in) :: value
    character(len=:), allocatable :: text
    character(len=32) :: buffer
    write (buffer, '(es24.16e3)') value
    text = trim(adjustl(buffer))
  end function real_text

  !> After a failed write (every rank has closed the file): rank 0 removes the temporary, so
  !> no .tmp is left behind; the error already says what failed, a failed removal adds nothing.
  subroutine discard(par, temporary)
    type(parallel_t), intent(in) :: par
    character(len=*), intent(in) :: temporary
    type(error_t) :: ignored
    call par%barrier()
    if (par%is_root()) call remove_file(temporary, ignored)
  end subroutine discard

  !> Every rank learns that some rank failed; ranks without their own message get `message`.
  subroutine agree(par, err, message)
    type(parallel_t), intent(in) :: par
    type(error_t), intent(inout) :: err
    character(len=*), intent(in) :: message
    if (par%any(err%failed()) .and. err%ok()) call err%set(ERR_IO, message)
  end subroutine agree

end module frame_writer
