!> `ricochet --check DECK`: every start-up check of a real run without stepping (meshes
!> read, welded and validated, bodies built, overlap check, grid and minimum separation,
!> event loop choice), then what the bodies are: per body its shape, volume, mass, centre of
!> mass, principal moments and axes, and the smallest initial gap with the pair that has it.
!> Nothing is written to the output folder.
module startup_report
  use kinds, only: dp, i8
  use error_status, only: error_t
  use string_utils, only: str, join_reals
  use quaternion, only: quat_to_matrix
  use input_config, only: deck_t
  use shape, only: shape_library_t
  use body_state, only: bodies_t
  use body_labels, only: body_label
  use body_builder, only: build_shapes, build_bodies, count_bodies, build_materials
  use contact_material, only: material_table_t
  use overlap_check, only: check_initial_overlaps, nearby_pairs
  use resolution_check, only: check_position_resolution
  use collision_stage, only: collision_stage_t, smallest_moving_extent
  use pair_geometry, only: pair_gap
  use simulation, only: choose_event_loop
  implicit none
  private
  public :: check_deck, max_bodies_listed

  !> Bodies listed one by one up to this many; beyond, the first body of each &body group
  !> (a lattice of 10^6 copies would bury the answer).
  integer, parameter :: max_bodies_listed = 200

contains

  subroutine check_deck(deck, unit, err)
    type(deck_t), intent(in) :: deck
    integer, intent(in) :: unit
    type(error_t), intent(inout) :: err
    type(shape_library_t) :: shapes
    type(bodies_t) :: bodies
    type(collision_stage_t) :: collisions
    type(material_table_t) :: materials
    integer, allocatable :: shape_of_group(:)
    integer :: i, pair(2)
    real(dp) :: gap, reach
    logical :: each, local

    call build_shapes(deck, shapes, shape_of_group, err)
    if (err%failed()) return
    call build_bodies(deck, shapes, shape_of_group, deck%run%gravity, 1_i8, count_bodies(deck), bodies, err)
    if (err%failed()) return
    call check_initial_overlaps(deck, shapes, bodies, err)
    if (err%failed()) return
    ! The grid box and the minimum separation are checked against the bodies here.
    call build_materials(deck, materials)
    call collisions%init(deck%contact, deck%run, materials, deck%path, shapes, bodies, err, &
                         smallest_extent=smallest_moving_extent(shapes, bodies))
    if (err%failed()) return
    call check_position_resolution(deck, shapes, bodies, collisions%target, deck%contact%min_separation <= 0.0_dp, err)
    if (err%failed()) return
    call choose_event_loop(deck, local, err)
    if (err%failed()) return
    call smallest_gap(shapes, bodies, collisions%box_size, gap, pair, err)
    if (err%failed()) return

    write (unit, '(a)') '! start-up checks passed: meshes read, welded and validated; '//str(bodies%n_owned)// &
      ' bodies of '//str(shapes%n_shapes)//' distinct shapes built; no two overlap; grid box '// &
      str(collisions%box_size, '(es10.3)')//' m, minimum separation '//str(collisions%target, '(es10.3)')//' m, '// &
      trim(merge('local ', 'global', local))//' event loop'
    each = bodies%n_owned <= max_bodies_listed
    if (each) then
      write (unit, '(a)') '! bodies (centre of mass [m], principal moments [kg m^2], principal axes in the world frame):'
    else
      write (unit, '(a)') '! the first body of each &body group ('//str(bodies%n_owned)//' bodies; every body is '// &
        'listed up to '//str(max_bodies_listed)//'):'
    end if
    do i = 1, bodies%n_owned
      if (.not. each) then
        if (i > 1) then
          if (bodies%group_id(i) == bodies%group_id(i - 1)) cycle
        end if
      end if
      call describe_body(deck, shapes, bodies, i, unit)
    end do
    if (pair(1) > 0) then
      write (unit, '(a)') '! smallest initial gap '//str(gap, '(es10.3)')//' m, between '// &
        body_label(deck, bodies, pair(1))//' and '//body_label(deck, bodies, pair(2))
    else
      reach = collisions%box_size
      write (unit, '(a)') '! smallest initial gap: no two bodies (not both fixed) within one grid box ('// &
        str(reach, '(es10.3)')//' m) of each other'
    end if
  end subroutine check_deck

  subroutine describe_body(deck, shapes, bodies, i, unit)
    type(deck_t), intent(in) :: deck
    type(shape_library_t), intent(in) :: shapes
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: i, unit
    real(dp) :: axes(3, 3)
    associate (s => shapes%shapes(bodies%shape_id(i)))
      axes = quat_to_matrix(bodies%q(:, i))
      if (bodies%fixed(i)) then
        write (unit, '(a)') '!   '//body_label(deck, bodies, i)//': '//s%label//', fixed, volume '// &
          str(s%volume, '(es12.5)')//' m^3, centre '//join_reals(bodies%x(:, i), '(es11.4)', ' ')
      else
        write (unit, '(a)') '!   '//body_label(deck, bodies, i)//': '//s%label//', volume '// &
          str(s%volume, '(es12.5)')//' m^3, mass '//str(bodies%mass(i), '(es12.5)')//' kg'
        write (unit, '(a)') '!       centre of mass '//join_reals(bodies%x(:, i), '(es11.4)', ' ')// &
          '; principal moments '//join_reals(bodies%inertia(:, i), '(es11.4)', ' ')
        write (unit, '(a)') '!       principal axes ('//join_reals(axes(:, 1), '(es11.4)', ' ')//'), ('// &
          join_reals(axes(:, 2), '(es11.4)', ' ')//'), ('//join_reals(axes(:, 3), '(es11.4)', ' ')//')'
      end if
    end associate
  end subroutine describe_body

  !> The smallest gap over the pairs the grid finds within one box of each other (not both
  !> fixed); pair = 0 when there is none.
  subroutine smallest_gap(shapes, bodies, box_size, gap, pair, err)
    type(shape_library_t), intent(in) :: shapes
    type(bodies_t), intent(in) :: bodies
    real(dp), intent(in) :: box_size
    real(dp), intent(out) :: gap
    integer, intent(out) :: pair(2)
    type(error_t), intent(inout) :: err
    integer, allocatable :: pairs(:, :)
    real(dp) :: g, normal(3)
    integer :: n, k, i, j, n_pairs
    gap = huge(1.0_dp)
    pair = 0
    n = bodies%n_owned
    if (n < 2) return
    call nearby_pairs(shapes, bodies, box_size, pairs, n_pairs, err)
    if (err%failed()) return
    do k = 1, n_pairs
      i = pairs(1, k)
      j = pairs(2, k)
      if (bodies%fixed(i) .and. bodies%fixed(j)) cycle
      call pair_gap(shapes, bodies, i, j, bodies%x(:, i), bodies%q(:, i), bodies%x(:, j), bodies%q(:, j), g, normal)
      if (g < gap) then
        gap = g
        pair = [min(i, j), max(i, j)]
      end if
    end do
  end subroutine smallest_gap



end module startup_report
