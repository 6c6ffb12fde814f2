!> How messages and reports name a body: "body 7 'crate' (&body #2)", its global id, the
!> name and the index of the &body group that made it.
module body_labels
  use string_utils, only: str
  use input_config, only: deck_t
  use body_state, only: bodies_t
  implicit none
  private
  public :: body_label

contains

  function body_label(deck, bodies, i) result(text)
    type(deck_t), intent(in) :: deck
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: i          !< row in bodies
    character(len=:), allocatable :: text
    integer :: k
    k = bodies%group_id(i)
    text = 'body '//str(bodies%gid(i))
    ! (a checkpoint's row may name a group the deck does not have)
    if (k >= 1 .and. k <= deck%n_bodies) text = text//" '"//trim(deck%bodies(k)%name)//"' (&body #"//str(k)//')'
  end function body_label

end module body_labels
