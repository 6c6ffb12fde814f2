!> An undo journal of rows, for the states a cross-rank window saves (docs/architecture.md,
!> "Cross-rank contacts: windows with ghosts", step 4): a save that copied every array of a
!> rank cost what the rank holds (90 MB for 50,000 spheres, more than the window's own
!> events); with a journal it costs what the window changes.
!>
!> The owner of the arrays numbers its rows (a body, a pair slot, a queue handle) and packs
!> a row into a fixed number of 64-bit words. Before the first change of row i since start,
!> it asks `keep(i)`: a column of `words` to pack the row into (0: no journal runs, or the
!> row is kept already). To roll back, it unpacks words(:, m) into row ids(m) for m = 1..n
!> (each row is kept once, so the order does not matter), then calls `clear`: the journal
!> goes on from the rolled-back state. O(rows changed) for keep, clear and stop; the flags
!> grow with the highest row id seen.
module row_journal
  use kinds, only: i8
  implicit none
  private
  public :: row_journal_t

  type :: row_journal_t
    logical :: active = .false.
    integer :: width = 0                      !< words per row
    integer :: n = 0                          !< rows kept
    logical, allocatable :: kept(:)           !< per row id: kept since start (or the last clear)
    integer, allocatable :: ids(:)            !< the rows kept, in order
    integer(i8), allocatable :: words(:, :)   !< (width, m): row ids(m) as it was
  contains
    procedure :: start => journal_start
    procedure :: keep => journal_keep
    procedure :: clear => journal_clear
    procedure :: stop => journal_stop
  end type row_journal_t

contains

  !> From now on the first change of each row is kept (rows_hint: the rows there are now, a
  !> size for the flags; width: words per row).
  subroutine journal_start(self, rows_hint, width)
    class(row_journal_t), intent(inout) :: self
    integer, intent(in) :: rows_hint, width
    call self%clear()
    if (allocated(self%kept)) then
      if (size(self%kept) < rows_hint) deallocate (self%kept)
    end if
    if (.not. allocated(self%kept)) then
      allocate (self%kept(max(rows_hint, 16)))
      self%kept = .false.
    end if
    if (allocated(self%words)) then
      if (size(self%words, 1) /= width) deallocate (self%ids, self%words)
    end if
    if (.not. allocated(self%ids)) allocate (self%ids(64), self%words(width, 64))
    self%width = width
    self%active = .true.
  end subroutine journal_start

  !> Row i is about to change: the column of words to pack it into, the first time since
  !> start or clear; 0 otherwise (or if no journal runs).
  integer function journal_keep(self, i) result(column)
    class(row_journal_t), intent(inout) :: self
    integer, intent(in) :: i
    logical, allocatable :: kept(:)
    integer, allocatable :: ids(:)
    integer(i8), allocatable :: words(:, :)
    column = 0
    if (.not. self%active) return
    if (i > size(self%kept)) then
      allocate (kept(max(i, 2*size(self%kept))))
      kept = .false.
      kept(1:size(self%kept)) = self%kept
      call move_alloc(kept, self%kept)
    end if
    if (self%kept(i)) return
    self%kept(i) = .true.
    if (self%n == size(self%ids)) then
      allocate (ids(2*self%n), words(self%width, 2*self%n))
      ids(1:self%n) = self%ids(1:self%n)
      words(:, 1:self%n) = self%words(:, 1:self%n)
      call move_alloc(ids, self%ids)
      call move_alloc(words, self%words)
    end if
    self%n = self%n + 1
    self%ids(self%n) = i
    column = self%n
  end function journal_keep

  !> Nothing kept (after a roll back: the journal goes on from the state rolled back to).
  subroutine journal_clear(self)
    class(row_journal_t), intent(inout) :: self
    integer :: m
    if (allocated(self%kept)) then
      do m = 1, self%n
        self%kept(self%ids(m)) = .false.
      end do
    end if
    self%n = 0
  end subroutine journal_clear

  !> No more journal (the rows kept are dropped).
  subroutine journal_stop(self)
    class(row_journal_t), intent(inout) :: self
    call self%clear()
    self%active = .false.
  end subroutine journal_stop

end module row_journal
