!> Where the effective deck's lines go (deck_reader write_effective_deck,
!> effective_deck_lines): a Fortran unit (a file a user reads: every line as written), or
!> memory (what a checkpoint stores: comment lines and trailing comments dropped, lines
!> left-adjusted, '&body ! #3' as '&body #3'). Memory spares the scratch file the lines went
!> through before (written, then read back line by line: a third of the effective deck's
!> cost at 100,000 bodies, docs/benchmarks.md).
module deck_sink
  implicit none
  private
  public :: deck_sink_t

  type :: deck_sink_t
    logical :: in_memory = .false.                !< the lines are kept here, not written to unit
    integer :: unit = 0                           !< (newunit= numbers are negative)
    character(len=:), allocatable :: text         !< in memory: the kept lines one after another
    integer, allocatable :: ends(:)               !< ... line k ends at ends(k) in text
    integer :: n = 0                              !< lines kept
    integer :: used = 0                           !< characters of text in use
    integer :: width = 1                          !< the longest line kept
  contains
    procedure :: to_unit => sink_to_unit
    procedure :: to_memory => sink_to_memory
    procedure :: put => sink_put
    procedure :: take_lines => sink_take_lines
  end type deck_sink_t

contains

  subroutine sink_to_unit(self, unit)
    class(deck_sink_t), intent(inout) :: self
    integer, intent(in) :: unit
    self%unit = unit
    self%in_memory = .false.
  end subroutine sink_to_unit

  subroutine sink_to_memory(self)
    class(deck_sink_t), intent(inout) :: self
    self%in_memory = .true.
    if (allocated(self%text)) deallocate (self%text)
    if (allocated(self%ends)) deallocate (self%ends)
    allocate (character(len=65536) :: self%text)
    allocate (self%ends(1024))
    self%n = 0
    self%used = 0
    self%width = 1
  end subroutine sink_to_memory

  !> One line of the deck.
  subroutine sink_put(self, line)
    class(deck_sink_t), intent(inout) :: self
    character(len=*), intent(in) :: line
    character(len=:), allocatable :: grown_text
    integer, allocatable :: grown(:)
    integer :: first, last, k
    if (.not. self%in_memory) then
      write (self%unit, '(a)') line
      return
    end if
    first = verify(line, ' ')
    if (first == 0) return                        ! (blank)
    if (line(first:first) == '!') return          ! (a comment line)
    last = len_trim(line)
    if (last - first >= 7) then
      if (line(first:first + 7) == '&body ! ') then
        call keep('&body '//trim(adjustl(line(first + 8:last))))
        return
      end if
    end if
    k = comment_start(line(first:last))
    if (k > 0) then
      call keep(trim(line(first:first + k - 2)))
    else
      call keep(line(first:last))
    end if
  contains
    subroutine keep(kept)
      character(len=*), intent(in) :: kept
      integer :: length
      length = len(kept)
      if (length == 0) return
      if (self%used + length > len(self%text)) then
        allocate (character(len=2*(self%used + length)) :: grown_text)
        grown_text(1:self%used) = self%text(1:self%used)
        call move_alloc(grown_text, self%text)
      end if
      if (self%n == size(self%ends)) then
        allocate (grown(2*self%n))
        grown(1:self%n) = self%ends(1:self%n)
        call move_alloc(grown, self%ends)
      end if
      self%text(self%used + 1:self%used + length) = kept
      self%used = self%used + length
      self%n = self%n + 1
      self%ends(self%n) = self%used
      self%width = max(self%width, length)
    end subroutine keep
  end subroutine sink_put

  !> The lines kept in memory, each as wide as the longest (the sink is emptied: to_memory
  !> starts it again).
  subroutine sink_take_lines(self, lines)
    class(deck_sink_t), intent(inout) :: self
    character(len=:), allocatable, intent(out) :: lines(:)
    integer :: k, start
    allocate (character(len=self%width) :: lines(self%n))
    start = 1
    do k = 1, self%n
      lines(k) = self%text(start:self%ends(k))
      start = self%ends(k) + 1
    end do
    deallocate (self%text, self%ends)
    self%n = 0
    self%used = 0
    self%width = 1
  end subroutine sink_take_lines

  !> Where a '!' comment starts outside quotes (0: none).
  pure integer function comment_start(line) result(at)
    character(len=*), intent(in) :: line
    character :: quote
    integer :: i
    quote = ' '
    at = 0
    do i = 1, len_trim(line)
      if (quote /= ' ') then
        if (line(i:i) == quote) quote = ' '
      else if (line(i:i) == '''' .or. line(i:i) == '"') then
        quote = line(i:i)
      else if (line(i:i) == '!') then
        at = i
        return
      end if
    end do
  end function comment_start

end module deck_sink
