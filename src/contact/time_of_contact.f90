!> Time of contact of one pair by conservative advancement: from the closest points (gap d,
!> normal n) bound how much the pair can close over t (advancement_bound), advance to the
!> earliest time that bound reaches d - target, recompute the closest points there, repeat
!> until the gap is within the tolerance of the target, or the step ends first.
!>
!> Each advance is safe by construction: the bound holds for the motion the integrator
!> makes, so the true gap at the new time is >= target. The loop therefore never passes
!> through a contact, whatever the speeds: no tunnelling.
!>
!> The oracle may know a tighter bound from the poses it computes (turning_time: for convex
!> pairs on the exact propagator, turning_bound's directional bound and plane_bound's from
!> each iterate); every advance then takes the later of the two times, each of which is safe.
module time_of_contact
  use kinds, only: dp, i8
  use advancement_bound, only: closing_bound_t, time_to_close, closing_bound_along, closing_bound_any
  implicit none
  private
  public :: pair_motion_t, advancement_result_t, distance_oracle_t, advance_pair

  !> What the bound needs of a pair over the step: each body's velocity and acceleration at
  !> the start of the step, its angular speed bound times its largest radius, and whether
  !> the single-direction (convex) bound applies.
  type :: pair_motion_t
    real(dp) :: v_a(3) = 0.0_dp, a_a(3) = 0.0_dp, omega_r_a = 0.0_dp
    real(dp) :: v_b(3) = 0.0_dp, a_b(3) = 0.0_dp, omega_r_b = 0.0_dp
    logical :: convex = .true.
  end type pair_motion_t

  type :: advancement_result_t
    logical :: contact = .false.      !< the gap reaches target + tolerance within the step
    real(dp) :: time = 0.0_dp         !< time of contact, or the step length if none [s]
    !> gap at `time` (last one computed; a lower bound when the oracle gave one there) [m]
    real(dp) :: gap = 0.0_dp
    real(dp) :: normal(3) = 0.0_dp    !< normal there, from a to b
    integer :: iterations = 0         !< closest-point queries made
    logical :: capped = .false.       !< stopped by the iteration cap (time is still safe)
    !> the canonical time of contact as an absolute time (canonical_crossing), -huge if none:
    !> origin + time gives it back only where the sum is exact, and a caller that stores
    !> absolute times takes it from here, so that it does not depend on the origin [s]
    real(dp) :: t_absolute = -huge(1.0_dp)
  end type advancement_result_t

  !> Closest points of the pair with both bodies moved forward by t from the step's start.
  !> An oracle that can also evaluate the pair at an absolute time, bit for bit whatever the
  !> step's start (`canonical`, `origin` = the absolute time of t = 0, `gap_at_time`), gets
  !> its times of contact made canonical (canonical_crossing).
  !> turning_time: a second bound the oracle may know (turning_bound's directional one, from
  !> the poses it has): how long from t the pair stays above `above` along normal; 0 (the
  !> default) when it has none. advance_pair advances by the later of it and its own bound.
  type, abstract :: distance_oracle_t
    logical :: canonical = .false.
    real(dp) :: origin = 0.0_dp   !< absolute time of t = 0 [s]
  contains
    procedure(gap_at_interface), deferred :: gap_at
    procedure :: gap_at_time => default_gap_at_time
    procedure :: lower_gap_at => default_lower_gap_at
    procedure :: turning_time => no_turning_time
  end type distance_oracle_t

  abstract interface
    subroutine gap_at_interface(self, t, gap, normal)
      import :: distance_oracle_t, dp
      class(distance_oracle_t), intent(inout) :: self
      real(dp), intent(in) :: t          !< time since the step's start [s]
      real(dp), intent(out) :: gap       !< distance between the surfaces [m]
      real(dp), intent(out) :: normal(3) !< unit normal from a to b at the closest points
    end subroutine gap_at_interface
  end interface

contains

  !> Closest points at the absolute time t_abs (an oracle that is canonical overrides this
  !> with an evaluation that does not go through the step's start).
  subroutine default_gap_at_time(self, t_abs, gap, normal)
    class(distance_oracle_t), intent(inout) :: self
    real(dp), intent(in) :: t_abs
    real(dp), intent(out) :: gap, normal(3)
    call self%gap_at(t_abs - self%origin, gap, normal)
  end subroutine default_gap_at_time
  !> A lower bound on the gap at t and the direction along which the bodies are separated
  !> by exactly that much (exact = .true.: it is the gap, from gap_at). An oracle with a
  !> cheaper certified bound (convex pairs: convex_distance's GJK) overrides it; advance_pair
  !> takes it for the iterates above the band, where every closing bound it uses (along the
  !> normal, turning_bound's, plane_bound's) bounds the separation along that direction.
  subroutine default_lower_gap_at(self, t, gap, normal, exact)
    class(distance_oracle_t), intent(inout) :: self
    real(dp), intent(in) :: t
    real(dp), intent(out) :: gap, normal(3)
    logical, intent(out) :: exact
    call self%gap_at(t, gap, normal)
    exact = .true.
  end subroutine default_lower_gap_at
  !> No second bound: advance_pair uses its own.
  real(dp) function no_turning_time(self, t, normal, above, horizon) result(dt)
    class(distance_oracle_t), intent(inout) :: self
    real(dp), intent(in) :: t, normal(3), above, horizon
    dt = 0.0_dp
  end function no_turning_time

  !> Advances the pair over [0, step] towards the gap `target` (the minimum separation).
  !> gap0/normal0: the closest points at t = 0 (the caller has them from the broad phase).
  !>
  !> A pair already within the contact band (gap <= target + tolerance):
  !>  - approaching faster than velocity_tolerance: contact now (an impulse follows);
  !>  - separating faster than that: it may not come closer than it is, so it flies until
  !>    the bound says it could be back (a bouncing ball returns to the same gap);
  !>  - the bound says "may approach" but the caller measured that no contact point does
  !>    (spinning bodies just after an impulse): it may settle towards `floor`, as below;
  !>  - neither (resting, or equal speeds up to round-off, as in a Newton's cradle): it may
  !>    settle by at most the distance to `floor` (< target), so round-off in the relative
  !>    velocity never stalls the run, and no gap ever falls below the floor.
  subroutine advance_pair(oracle, motion, gap0, normal0, step, target, tolerance, floor, velocity_tolerance, &
                          max_iterations, result, receding, safe_time, hovering, refine)
    class(distance_oracle_t), intent(inout) :: oracle
    type(pair_motion_t), intent(in) :: motion
    real(dp), intent(in) :: gap0, normal0(3), step, target, tolerance
    real(dp), intent(in) :: floor                !< smallest gap a resting pair may settle to [m]
    real(dp), intent(in) :: velocity_tolerance   !< closing speeds below this count as resting [m/s]
    integer, intent(in) :: max_iterations
    type(advancement_result_t), intent(out) :: result
    !> The caller measured that no contact point of the pair approaches at t = 0 (only the
    !> bound's turning term says it may): in the band it then settles instead of stopping.
    logical, intent(in), optional :: receding
    !> A time [s] before which the caller has shown (plane_bound) that the gap stays above
    !> the floor (in the band) or the band (outside it): every advance then reaches at least
    !> there, whichever of the two bounds allows more.
    real(dp), intent(in), optional :: safe_time
    !> The pair hovers just above the band (collision_stage): after a few queries past the
    !> safe time the step ends there instead of crawling on (see max_beyond_safe).
    logical, intent(in), optional :: hovering
    !> A contact reached from above the band is moved to the time the gap crosses the aim,
    !> target + tolerance/2, to round-off (refine_crossing; default .true.): the time of
    !> contact is then a property of the two trajectories, not of the time the advancement
    !> started from, so the global and the local event loop find the same impacts.
    logical, intent(in), optional :: refine
    type(closing_bound_t) :: bound
    real(dp) :: t_before, gap_before
    logical :: do_refine
    logical :: measured_receding
    real(dp) :: t, gap, normal(3), dt, aim, safe
    integer :: beyond_safe
    logical :: crawl_limited
    logical :: separating, probed, exact
    !> With a second-order safe time, a pair hovering just above the band would make the
    !> first-order bound crawl (each query moves the gap little while the turning term says
    !> it may close fast): after this many queries the step ends there (capped, safe) and
    !> the next step starts from a fresh second-order bound.
    integer, parameter :: max_beyond_safe = 4
    ! Aim half a tolerance above the target: an exact bound then lands inside
    ! [target, target + tolerance] with round-off to spare, never just below the target.
    aim = target + 0.5_dp*tolerance
    measured_receding = .false.
    if (present(receding)) measured_receding = receding
    do_refine = .true.
    if (present(refine)) do_refine = refine
    t = 0.0_dp
    gap = gap0
    normal = normal0
    safe = 0.0_dp
    if (present(safe_time)) safe = safe_time
    if (safe >= step) then
      result%time = step
      result%gap = gap
      result%normal = normal
      return
    end if
    beyond_safe = 0
    crawl_limited = .false.
    probed = .false.
    separating = dot_product(normal0, motion%v_a - motion%v_b) < -velocity_tolerance
    t_before = 0.0_dp
    gap_before = gap0
    if (present(hovering)) crawl_limited = hovering .and. safe > 0.0_dp
    do
      if (result%iterations >= max_iterations .or. beyond_safe > max_beyond_safe) then
        result%capped = .true.
        exit
      end if
      bound = closing_bound(motion, normal, t)
      if (gap > target + tolerance) then
        ! either bound is safe, so the later of the two
        dt = max(time_to_close(bound, gap - aim), oracle%turning_time(t, normal, aim, step - t))
      else if (bound%rate > velocity_tolerance .and. .not. (measured_receding .and. t == 0.0_dp)) then
        result%contact = .true.       ! in the band and approaching: an event now
        ! unless it starts above the aim (a step of the caller ended there): the contact is
        ! the crossing of the aim, wherever the advancement started
        if (do_refine .and. t == 0.0_dp .and. gap > aim) &
          call refine_crossing(oracle, motion, step, target, aim, tolerance, t, gap, t, gap, normal, result)
        exit
      else if (bound%rate < -velocity_tolerance) then
        dt = time_to_close(bound, 0.0_dp)
      else
        dt = time_to_close(bound, max(gap - floor, 0.0_dp))
        if (gap > floor) dt = max(dt, oracle%turning_time(t, normal, floor, step - t))
      end if
      if (dt >= step - t) then
        t = step
        exit
      end if
      ! Up to `safe` the caller's second-order bound holds: the later of the two is safe.
      if (t + dt < safe) dt = safe - t
      if (dt <= 0.0_dp) then
        result%contact = .true.
        exit
      end if
      t_before = t
      gap_before = gap
      t = t + dt
      if (crawl_limited) beyond_safe = beyond_safe + 1
      ! Above the band a certified lower bound is all the next advance needs; in the band
      ! the exact gap decides (contact or not, refinement, settling).
      call oracle%lower_gap_at(t, gap, normal, exact)
      if (.not. exact .and. gap <= target + tolerance) call oracle%gap_at(t, gap, normal)
      result%iterations = result%iterations + 1
      if (gap <= target + tolerance .and. do_refine .and. gap_before <= target + tolerance .and. &
          separating .and. .not. probed) then
        ! Started in the band, separating, and back in it after a jump (a second-order safe
        ! time): the pair may have left the band and come back (a bounce, then another corner
        ! turning in). Its contact is then the crossing of the aim on the way back, not this
        ! point, which depends on where the advancement started: look for a time above the
        ! band in between and advance from there (first-order, refined) instead.
        probed = .true.
        call find_above_band(t_before, t, gap, normal)
        if (gap > target + tolerance) then
          safe = 0.0_dp
          crawl_limited = .false.
          cycle
        end if
      end if
      if (gap <= target + tolerance) then
        result%contact = .true.
        ! from above the band, aiming at `aim`: the crossing of the aim, exactly
        if (do_refine .and. gap_before > target + tolerance) &
          call refine_crossing(oracle, motion, step, target, aim, tolerance, t_before, gap_before, t, gap, normal, &
                               result)
        exit
      end if
    end do
    result%time = t
    result%gap = gap
    result%normal = normal
  contains
    !> Probes at 1/2, 1/4 and 3/4 of [t1, t2]: on return (t, g, n) is the first one above the
    !> band, or (t2, g, n) unchanged if none is.
    subroutine find_above_band(t1, t2, g, n)
      real(dp), intent(in) :: t1
      real(dp), intent(inout) :: t2, g, n(3)
      real(dp), parameter :: fractions(3) = [0.5_dp, 0.25_dp, 0.75_dp]
      real(dp) :: tm, gm, nm(3)
      integer :: m
      do m = 1, size(fractions)
        tm = t1 + fractions(m)*(t2 - t1)
        call oracle%gap_at(tm, gm, nm)
        result%iterations = result%iterations + 1
        if (gm > target + tolerance) then
          t2 = tm
          g = gm
          n = nm
          return
        end if
      end do
    end subroutine find_above_band
  end subroutine advance_pair

  !> The time the gap crosses `aim` (target + tolerance/2), after conservative advancement
  !> landed at t (gap in [aim, target + tolerance] there; t_prev, gap_prev: the iterate
  !> before). The advancement approaches the crossing from below in time at a rate set by
  !> how loose its bound is (turning bodies: linearly, slowly); here a secant step on the
  !> measured gaps, bracketed once a probe falls below the aim (regula falsi, Illinois), finds
  !> it to round-off in a few queries. Every probe stays within what the bound certifies
  !> from the last point above the aim, gap >= target, so no committed time is ever closer
  !> than the target. If the crossing lies beyond the step, the pair has no contact in it.
  !> On return t is the crossing (or the last safe point above it when the queries ran out;
  !> once bracketed, the point below the aim if the one above never reached the band).
  subroutine refine_crossing(oracle, motion, step, target, aim, tolerance, t_prev, gap_prev, t, gap, normal, result)
    class(distance_oracle_t), intent(inout) :: oracle
    type(pair_motion_t), intent(in) :: motion
    real(dp), intent(in) :: step, target, aim, tolerance
    real(dp), intent(in) :: t_prev, gap_prev
    real(dp), intent(inout) :: t, gap, normal(3)
    type(advancement_result_t), intent(inout) :: result
    !> Queries beyond the advancement's own; the secant converges superlinearly.
    integer, parameter :: max_refinements = 60
    real(dp) :: lo, g_lo, n_lo(3), lo_prev, g_lo_prev, hi, g_hi, n_hi(3), s, g_s, n_s(3), limit, slope, eps_gap
    real(dp) :: f_lo, f_hi       ! regula falsi: gap - aim at lo and hi, Illinois-weighted
    type(closing_bound_t) :: bound_lo
    logical :: bracketed, beyond
    integer :: k, side, stalled
    real(dp) :: best
    !> Probes in a row that do not come closer to the aim: the gap is at its round-off.
    integer, parameter :: max_stalled = 3
    ! gaps are measured to round-off of the positions (1e-16 m at 1 m from the origin); the
    ! search goes on to that, or until the bracket is a few floating-point times wide, or
    ! until probes stop coming closer (round-off of the gap larger than eps_gap)
    eps_gap = 1.0e-10_dp*tolerance
    stalled = 0
    lo = t
    g_lo = gap
    n_lo = normal
    lo_prev = t_prev
    g_lo_prev = gap_prev
    bracketed = .false.
    hi = huge(1.0_dp)
    g_hi = huge(1.0_dp)
    n_hi = normal
    f_lo = g_lo - aim
    f_hi = 0.0_dp
    side = 0
    beyond = .false.
    if (gap < aim - eps_gap) then
      ! Past the aim already: a second-order safe time (plane_bound) let the advancement
      ! jump beyond it, to a point it certified (gap >= its floor up to there); the crossing
      ! lies between the point before and this one.
      lo = t_prev
      g_lo = gap_prev
      n_lo = normal
      f_lo = g_lo - aim
      hi = t
      g_hi = gap
      n_hi = normal
      f_hi = gap - aim
      bracketed = .true.
      side = -1
    end if
    best = abs(g_lo - aim)
    do k = 1, max_refinements
      if (abs(g_lo - aim) <= eps_gap .or. stalled >= max_stalled) exit
      ! the bound from lo: every time up to `limit` keeps the gap at or above the target
      ! (or the oracle's own bound from lo, when it allows more: either is safe)
      limit = min(step, lo + max(time_to_close(closing_bound(motion, n_lo, lo), g_lo - target), &
                                 oracle%turning_time(lo, n_lo, target, step - lo)))
      if (bracketed) then
        if (hi - lo <= 4.0_dp*spacing(hi)) exit
        s = lo + f_lo*(hi - lo)/(f_lo - f_hi)
        if (.not. (s > lo .and. s < hi)) s = 0.5_dp*(lo + hi)
      else
        slope = 0.0_dp                 ! (no point before lo when starting in the band)
        if (lo > lo_prev) slope = (g_lo - g_lo_prev)/(lo - lo_prev)
        if (.not. (slope < 0.0_dp)) then
          ! not closing between the last two points: the bound's rate
          bound_lo = closing_bound(motion, n_lo, lo)
          slope = -bound_lo%rate
          if (.not. (slope < 0.0_dp)) then
            ! the pair cannot close from here: no contact yet, safe up to lo
            beyond = .true.
            exit
          end if
        end if
        s = lo + (g_lo - aim)/(-slope)
      end if
      if (s > limit) then
        if (limit <= lo) exit
        s = limit
      end if
      call oracle%gap_at(s, g_s, n_s)
      result%iterations = result%iterations + 1
      if (abs(g_s - aim) < best) then
        best = abs(g_s - aim)
        stalled = 0
      else
        stalled = stalled + 1
      end if
      if (abs(g_s - aim) <= eps_gap) then
        lo = s
        g_lo = g_s
        n_lo = n_s
        exit
      else if (g_s > aim) then
        lo_prev = lo
        g_lo_prev = g_lo
        lo = s
        g_lo = g_s
        n_lo = n_s
        f_lo = g_s - aim
        if (bracketed .and. side == 1) f_hi = 0.5_dp*f_hi      ! Illinois: the stale end halves
        side = 1
        if (.not. bracketed .and. s >= step) then
          beyond = .true.                                       ! no crossing within the step
          exit
        end if
      else
        hi = s
        g_hi = g_s
        n_hi = n_s
        f_hi = g_s - aim
        if (bracketed .and. side == -1) f_lo = 0.5_dp*f_lo
        side = -1
        bracketed = .true.
      end if
    end do
    ! stopped at the step's end still above the aim: the crossing is beyond it
    if (lo >= step .and. abs(g_lo - aim) > eps_gap) beyond = .true.
    t = lo
    gap = g_lo
    normal = n_lo
    if (bracketed .and. gap > target + tolerance) then
      ! The search stopped before lo came into the band: its probes stalled at the gap's
      ! round-off (which can exceed eps_gap: 4e-15 m for a ball 3 m from a floor's centre,
      ! every probe near hi measuring the same gap), or ran out. hi is a measured point
      ! below the aim and certified (where the advancement itself landed, or a probe within
      ! the bound from a point above the aim), so the contact is there. Answering lo would
      ! say "no contact, safe only up to lo", and lo may be where the advancement started:
      ! the pair was then found capped at time 0 again and again, an impact that changed
      ! nothing (local loop: "collision loop stalled") or a step of length 0 (global loop).
      t = hi
      gap = g_hi
      normal = n_hi
    end if
    if (beyond .or. gap > target + tolerance) then
      ! the crossing is beyond the step, or not certified yet: no contact, and the pair is
      ! safe up to t (capped when that is before the step's end)
      result%contact = .false.
      result%capped = t < step
    else if (oracle%canonical) then
      call canonical_crossing(oracle, motion, step, target, aim, eps_gap, t, gap, normal, result)
    end if
  end subroutine refine_crossing

  !> The crossing found by refine_crossing (t, within round-off of the gap) made canonical:
  !> a function of the two trajectories alone, bit for bit, not of where the advancement
  !> started (the global loop starts at its step, the local one at the pair's certificate).
  !> The search above ends within the gap's round-off of the aim, so two starts give times
  !> that differ by up to round-off over the approach speed: 1e-13 s on a slow approach,
  !> which a gas amplifies through its later collisions. Here the crossing is looked for
  !> again on a fixed grid of absolute times, cells of 2^-40 s (9.1e-13 s): the cell at
  !> whose ends the gap, evaluated at those absolute times (gap_at_time), lies above and at
  !> or below the aim, then regula falsi (Illinois) inside it from its two ends, every probe
  !> an absolute time. Each value depends only on the trajectories and the absolute time,
  !> so any start that finds the crossing within a few cells finds the same cell and the
  !> same time. The answer is the last probe above the aim (the gap there is measured, so
  !> it is at least the target) unless one is within eps_gap of it, and it must lie within
  !> what the bound certifies from t: otherwise, or if no such cell is found within 2^24
  !> cells each way, t stays as it is.
  subroutine canonical_crossing(oracle, motion, step, target, aim, eps_gap, t, gap, normal, result)
    class(distance_oracle_t), intent(inout) :: oracle
    type(pair_motion_t), intent(in) :: motion
    real(dp), intent(in) :: step, target, aim, eps_gap
    real(dp), intent(inout) :: t, gap, normal(3)
    type(advancement_result_t), intent(inout) :: result
    real(dp), parameter :: cell = 2.0_dp**(-40)
    !> the bracket is looked for by steps of 1, 2, 4, ... cells, up to 2^24 cells (15 us)
    !> each way: a crossing refine_crossing found within its band, not within round-off of
    !> the aim (a stalled or capped search keeps the point below the aim it measured), can
    !> lie tens of cells from it, and a start that missed the cell by more than the 4 cells
    !> once searched kept its own time (an impact on 2 x 2 bricks came 5.6e-11 s apart)
    integer, parameter :: max_doublings = 24, max_probes = 12
    real(dp) :: t_abs, limit, lo, hi, g_lo, g_hi, n_lo(3), n_hi(3), f_lo, f_hi, s, g_s, n_s(3), best_t, best_g, &
                best_n(3), width
    integer :: k, side
    integer(i8) :: n_cells
    t_abs = oracle%origin + t
    ! (times beyond 2^12 s would leave the cells fewer bits than their ends need)
    if (.not. (abs(t_abs) < 4096.0_dp)) return
    ! what the bound certifies from the found point: every time up to there keeps gap >= target
    limit = oracle%origin + min(step, t + time_to_close(closing_bound(motion, normal, t), gap - target))
    lo = real(floor(t_abs/cell, kind=i8), dp)*cell
    hi = lo + cell
    call probe(lo, g_lo, n_lo)
    call probe(hi, g_hi, n_hi)
    width = cell
    do k = 1, max_doublings
      if (g_lo > aim) exit
      hi = lo
      g_hi = g_lo
      n_hi = n_lo
      lo = lo - width
      width = 2.0_dp*width
      call probe(lo, g_lo, n_lo)
    end do
    width = cell
    do k = 1, max_doublings
      if (g_hi <= aim) exit
      lo = hi
      g_lo = g_hi
      n_lo = n_hi
      hi = hi + width
      width = 2.0_dp*width
      call probe(hi, g_hi, n_hi)
    end do
    if (.not. (g_lo > aim .and. g_hi <= aim)) return
    ! down to one cell by halving on the grid (lo and hi are whole cells apart, exactly:
    ! multiples of 2^-40 s below 2^12 s): the cell where the gap crosses the aim, whichever
    ! start the search came from
    n_cells = nint((hi - lo)/cell, kind=i8)
    do while (n_cells > 1)
      s = lo + real(n_cells/2, dp)*cell
      call probe(s, g_s, n_s)
      if (g_s > aim) then
        lo = s
        g_lo = g_s
        n_lo = n_s
        n_cells = n_cells - n_cells/2
      else
        hi = s
        g_hi = g_s
        n_hi = n_s
        n_cells = n_cells/2
      end if
    end do
    best_t = lo
    best_g = g_lo
    best_n = n_lo
    if (abs(g_hi - aim) <= eps_gap) then
      best_t = hi
      best_g = g_hi
      best_n = n_hi
    end if
    f_lo = g_lo - aim
    f_hi = g_hi - aim
    side = 0
    do k = 1, max_probes
      if (abs(best_g - aim) <= eps_gap) exit
      if (hi - lo <= 4.0_dp*spacing(hi)) exit
      s = lo + f_lo*(hi - lo)/(f_lo - f_hi)
      if (.not. (s > lo .and. s < hi)) s = 0.5_dp*(lo + hi)
      call probe(s, g_s, n_s)
      if (abs(g_s - aim) <= eps_gap) then
        best_t = s
        best_g = g_s
        best_n = n_s
        exit
      else if (g_s > aim) then
        lo = s
        f_lo = g_s - aim
        if (side == 1) f_hi = 0.5_dp*f_hi
        side = 1
        best_t = s
        best_g = g_s
        best_n = n_s
      else
        hi = s
        f_hi = g_s - aim
        if (side == -1) f_lo = 0.5_dp*f_lo
        side = -1
      end if
    end do
    ! (below the target never: a point within eps_gap of the aim is far above it)
    if (best_g < target .or. best_t > limit) return
    ! relative to the origin, so that origin + t gives best_t back exactly where it can
    result%t_absolute = best_t
    t = best_t - oracle%origin
    if (oracle%origin + t > best_t) t = nearest(t, -1.0_dp)
    if (oracle%origin + t < best_t) t = nearest(t, 1.0_dp)
    gap = best_g
    normal = best_n
  contains
    subroutine probe(time_abs, g, n)
      real(dp), intent(in) :: time_abs
      real(dp), intent(out) :: g, n(3)
      call oracle%gap_at_time(time_abs, g, n)
      result%iterations = result%iterations + 1
    end subroutine probe
  end subroutine canonical_crossing

  !> The closing bound from time t on: velocities have changed by a t since the step began.
  pure function closing_bound(motion, n, t) result(bound)
    type(pair_motion_t), intent(in) :: motion
    real(dp), intent(in) :: n(3), t
    type(closing_bound_t) :: bound
    if (motion%convex) then
      bound = closing_bound_along(n, motion%v_a + motion%a_a*t, motion%a_a, motion%omega_r_a, &
                                  motion%v_b + motion%a_b*t, motion%a_b, motion%omega_r_b)
    else
      bound = closing_bound_any(motion%v_a + motion%a_a*t, motion%a_a, motion%omega_r_a, &
                                motion%v_b + motion%a_b*t, motion%a_b, motion%omega_r_b)
    end if
  end function closing_bound

end module time_of_contact
