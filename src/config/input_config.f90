!> The validated input of a run, apart from how it was read: deck_reader fills it from a
!> namelist deck, tests and tools can build it directly. Units in brackets. Defaults here
!> are the documented ones (docs/input.md); a negative value marked "auto" is replaced by a
!> value derived from the bodies when the run is set up.
module input_config
  use kinds, only: dp
  use constants, only: name_length, path_length
  implicit none
  private
  public :: run_config_t, parallel_config_t, integrator_config_t, contact_config_t, output_config_t, body_spec_t, &
            deck_t, ROTATION_NEWMARK, ROTATION_EXACT, EVENTS_AUTO, EVENTS_LOCAL, EVENTS_GLOBAL, &
            RULE_MIN, RULE_MAX, RULE_MEAN, RULE_GEOMETRIC

  character(len=*), parameter :: ROTATION_NEWMARK = 'newmark'
  character(len=*), parameter :: ROTATION_EXACT = 'exact'
  character(len=*), parameter :: EVENTS_AUTO = 'auto'
  character(len=*), parameter :: EVENTS_LOCAL = 'local'
  character(len=*), parameter :: EVENTS_GLOBAL = 'global'
  !> How a contact combines the materials of its two bodies (contact_material)
  character(len=*), parameter :: RULE_MIN = 'min'
  character(len=*), parameter :: RULE_MAX = 'max'
  character(len=*), parameter :: RULE_MEAN = 'mean'             !< arithmetic mean
  character(len=*), parameter :: RULE_GEOMETRIC = 'geometric'   !< sqrt(a b) (friction only)

  !> &parallel: how a run on several ranks is cut into bricks (docs/input.md).
  type :: parallel_config_t
    integer :: dims(3) = 0      !< ranks along x, y, z; 0: chosen (the longest axis cut first)
    !> [m] how far a body may leave its brick before it migrates to its new owner (-1: auto,
    !> one box of the collision grid; 0: at every brick it leaves)
    real(dp) :: skin = -1.0_dp
    !> [-] events per rank a cross-rank window aims at: its length is this many times the
    !> ranks over the run's event rate so far (-1: auto, 150; docs/architecture.md, "Window
    !> length")
    real(dp) :: window_events = -1.0_dp
  end type parallel_config_t

  type :: run_config_t
    character(len=256) :: title = 'ricochet run'
    real(dp) :: t_end = -1.0_dp              !< [s] required, > 0
    real(dp) :: dt_max = -1.0_dp             !< [s] required, > 0
    real(dp) :: gravity(3) = 0.0_dp          !< [m/s^2]
    !> [s] wall time of this run after which it writes a checkpoint and stops (0: no limit)
    real(dp) :: wall_limit = 0.0_dp
  end type run_config_t

  type :: integrator_config_t
    real(dp) :: newmark_beta = 0.25_dp
    real(dp) :: newmark_gamma = 0.5_dp
    real(dp) :: rotation_tolerance = 1.0e-14_dp   !< relative change of the rotation update [-]
    integer :: rotation_max_iterations = 50
    !> 'exact' (closed-form torque-free flight, default: docs/rotation.md, docs/benchmarks.md) or 'newmark'
    character(len=16) :: rotation = ROTATION_EXACT
    !> 'local': event-driven loop, bodies evaluated from anchors, pair bounds in a queue;
    !> 'global': every event a global step (the reference); 'auto': local with exact
    !> rotation, global with newmark
    character(len=16) :: events = EVENTS_AUTO
    !> local loop: after every event, check that every pair with a moving body holds a
    !> current certificate reaching at least to now (O(pairs) per event: for tests)
    logical :: audit_certificates = .false.
  end type integrator_config_t

  type :: contact_config_t
    real(dp) :: restitution = 0.5_dp         !< coefficient of restitution e in [0, 1]
    real(dp) :: friction = 0.0_dp            !< Coulomb coefficient mu >= 0
    !> e of a contact from its bodies' e: 'min' (default), 'max' or 'mean'
    character(len=16) :: restitution_rule = RULE_MIN
    !> mu of a contact from its bodies' mu: 'geometric' (default, sqrt(mu_a mu_b)), 'min', 'max' or 'mean'
    character(len=16) :: friction_rule = RULE_GEOMETRIC
    real(dp) :: min_separation = -1.0_dp     !< [m]; auto: 1e-4 of the smallest body size
    !> [m/s] impacts approaching slower than this are inelastic (resting contact, no Zeno
    !> sequence of ever smaller bounces); auto (-1): max(2 |g| dt_max, sqrt(2 |g| min_separation))
    real(dp) :: rest_speed = -1.0_dp
    !> [m/s] islands whose points all move slower than this for sleep_time fall asleep;
    !> 0: never; auto (-1): rest_speed/100 (so no sleeping without gravity)
    real(dp) :: sleep_speed = -1.0_dp
    real(dp) :: sleep_time = 0.5_dp          !< [s] quiet time before an island sleeps
    !> the contact pass allows for how the bodies' turning bends their contact points' paths
    !> over the step (second order; .false.: straight lines, as before 2026-12-07)
    logical :: turning_term = .true.
  end type contact_config_t

  type :: output_config_t
    character(len=path_length) :: dir = 'output'   !< relative to the deck's folder
    real(dp) :: interval = -1.0_dp                 !< [s]; auto: t_end/100
    real(dp) :: checkpoint_interval = 0.0_dp       !< [s]; 0: only at the end of the run
    real(dp) :: progress_interval = 10.0_dp        !< [s of wall time] between progress lines
    real(dp) :: history_interval = -1.0_dp         !< [s] between history rows; auto: interval/10
    logical :: write_frames = .true.               !< .false.: history and checkpoints only
    logical :: check_overlaps = .false.            !< exact overlap test of all bodies at every frame
    logical :: event_log = .false.                 !< events.csv: every body's impulses at every impact
  end type output_config_t

  !> One &body group: a body, or a lattice of copies of it.
  !> (No allocatable component: run/shared_deck gathers specs across ranks as their bits.)
  type :: body_spec_t
    character(len=name_length) :: name = ''
    !> 'sphere', 'box', 'cylinder', 'tetrahedron', 'torus', 'l_prism', 'mesh'
    character(len=16) :: shape = ''
    real(dp) :: radius = -1.0_dp             !< [m] sphere, cylinder; torus: major radius (tube centre circle)
    !> [m] box edge lengths; cylinder: size(3) is the length; tetrahedron: size(1) is the edge
    !> length; l_prism: outer x, y and extrusion z
    real(dp) :: size(3) = -1.0_dp
    integer :: segments = 32                 !< facets around a cylinder; torus: segments around its z axis
    real(dp) :: minor_radius = -1.0_dp       !< [m] torus: tube radius, 0 < minor_radius < radius
    integer :: tube_segments = 16            !< torus: segments around the tube
    real(dp) :: thickness = -1.0_dp          !< [m] l_prism: arm width, 0 < thickness < min(size(1), size(2))
    character(len=path_length) :: mesh_file = ''   !< resolved against the deck's folder
    real(dp) :: scale = 1.0_dp               !< mesh scale factor [-]
    real(dp) :: density = -1.0_dp            !< [kg/m^3] (density or mass, not both)
    real(dp) :: mass = -1.0_dp               !< [kg]
    real(dp) :: position(3) = 0.0_dp         !< [m] centre of mass (first copy)
    real(dp) :: orientation(4) = [1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp]   !< unit quaternion w,x,y,z
    real(dp) :: velocity(3) = 0.0_dp         !< [m/s]
    real(dp) :: angular_velocity(3) = 0.0_dp !< [rad/s] world frame
    logical :: fixed = .false.
    integer :: copies(3) = 1                 !< lattice nx, ny, nz
    real(dp) :: spacing(3) = 0.0_dp          !< [m] lattice spacing
    integer :: seed = 0                      !< random jitter seed (0: no jitter)
    real(dp) :: jitter_position = 0.0_dp     !< [m] max offset per axis
    real(dp) :: jitter_angle = 0.0_dp        !< [rad] max rotation angle
    real(dp) :: jitter_velocity = 0.0_dp     !< [m/s] max change per axis
    !> [kg m^2] moments about the shape's own x, y, z axes through the centre of mass,
    !> replacing those of the uniform solid (hollow or loaded bodies); auto (-1): from the
    !> geometry. The shape's inertia tensor must be diagonal in its own frame.
    real(dp) :: inertia(3) = -1.0_dp
    !> Material of the group's bodies (fixed ones too); -1: the &contact value. A pair
    !> combines them by &contact's restitution_rule and friction_rule (contact_material).
    real(dp) :: restitution = -1.0_dp        !< coefficient of restitution e in [0, 1] [-]
    real(dp) :: friction = -1.0_dp           !< Coulomb coefficient mu >= 0 [-]
    integer :: line = 0                      !< line of the deck where the group starts
  end type body_spec_t

  type :: deck_t
    character(len=:), allocatable :: path    !< the deck file as given
    character(len=:), allocatable :: folder  !< its folder: relative paths resolve here
    type(run_config_t) :: run
    type(integrator_config_t) :: integrator
    type(contact_config_t) :: contact
    type(output_config_t) :: output
    type(parallel_config_t) :: parallel
    integer :: n_bodies = 0                  !< number of &body groups
    type(body_spec_t), allocatable :: bodies(:)
  end type deck_t

end module input_config
