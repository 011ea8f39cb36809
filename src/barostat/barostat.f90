!> Pressure control: the abstract barostat that velocity Verlet calls, and what every style
!> shares. A style is one type extending barostat_t, in a file of its own (barostat_c_rescale,
!> barostat_mc); barostat_factory maps a style name to its type. The integrator calls the hooks
!> below and never asks which style it holds:
!>
!>   velocity Verlet, one step:   needs_virial (whether this step's force pass must give the virial)
!>                                replaces_kicks: first_half in place of the first half kick and the
!>                                drift, second_half in place of the second half kick (MTTK)
!>                                before_forces (after the drift, before the force pass: a change
!>                                of the box with the positions and velocities; C-rescale)
!>                                after_step (after the second half kick: a trial move of the box
!>                                judged on its energy; Monte Carlo)
!>   energy stepping:             apply_event (at the multiples of `interval`, a calendar entry:
!>                                Monte Carlo volume moves)
!>   both:                        follow (the thermostat's present target temperature, before the
!>                                step's hooks: a ramp moves the barostat's k T with it),
!>                                active, pv (the P V term of the conserved quantity), energy (the
!>                                barostat's own energy in it), exchange_own (a style's
!>                                own variables, to and from a checkpoint)
!>
!> A change of the box goes through the engine (engine%scale_box): positions and box scaled about
!> the origin, the domain's bricks following the box, atoms migrated and the neighbour list
!> rebuilt (Monte Carlo), or, for the small changes of every step (C-rescale, MTTK), the list kept
!> while the skin allows it, measured in positions scaled with the box. Every random number is drawn from the counter-based generator keyed by (seed, stream,
!> step), the same on every rank: a run gives the same decisions on any rank count and continues
!> bitwise after a restart.
!>
!> couple = 'aniso' (aniso): the box edges move independently, edge a driven by its own diagonal
!> pressure component P_aa = (2 K_aa + W_aa) / V (K_aa = sum m v_a^2 / 2, W_aa the virial's diagonal
!> that engine%compute_forces gives when engine%want_virial_diag is set; pressure_diagonal).
!>
!> Units: the pressure and compressibility arrive in the run's units (bar and 1/bar for metal) and
!> are held internally as energy/volume and volume/energy (divided and multiplied by nktv2p).
module terrace_barostat
    use terrace_kinds, only: dp, i8
    use terrace_engine, only: engine_t
    use terrace_velocities, only: kinetic_energy, atom_mass
    use terrace_mpi_env, only: sum_all
    use terrace_named_values, only: named_values_t
    use terrace_checkpointed, only: checkpointed_t
    implicit none
    private

    !> What a barostat is made from (the run's units applied).
    type, public :: barostat_params_t
        real(dp) :: pressure = 0                 !< target, in the run's pressure unit
        real(dp) :: damping = 1                  !< relaxation time (C-rescale tau_p)
        real(dp) :: compressibility = 0          !< the run's 1/pressure unit (C-rescale beta_T)
        real(dp) :: temperature = 0              !< the thermostat's target
        real(dp) :: dt = 0                       !< the integrator's time step
        integer(i8) :: seed = 1
        integer(i8) :: natoms = 0
        integer :: dimension = 3
        logical :: aniso = .false.               !< couple = 'aniso': each edge on its own
        integer :: every = 25                    !< Monte Carlo: steps between trial moves
        real(dp) :: interval = 0                 !< energy stepping: time between events (0: none)
        real(dp) :: boltz = 1, nktv2p = 1
    end type barostat_params_t

    type, abstract, extends(checkpointed_t), public :: barostat_t
        real(dp) :: p0 = 0                       !< target pressure (energy/volume)
        real(dp) :: beta = 0                     !< compressibility (volume/energy)
        real(dp) :: tau = 1
        real(dp) :: kt = 0                       !< k_B T of the thermostat's target
        type(barostat_params_t) :: p             !< as made (dt, seed, natoms, dimension, aniso, every, interval)
    contains
        procedure, non_overridable :: init => baro_init
        procedure :: setup => baro_setup
        procedure, non_overridable :: follow => baro_follow
        procedure :: retarget => baro_retarget
        procedure :: active => baro_active
        procedure :: needs_virial => baro_needs_virial
        procedure :: before_forces => baro_box_kept
        procedure :: after_step => baro_box_kept
        procedure :: apply_event => baro_box_kept
        procedure :: replaces_kicks => baro_replaces_kicks
        procedure :: first_half => baro_half
        procedure :: second_half => baro_half
        procedure :: energy => baro_energy
        procedure, non_overridable :: pv => baro_pv
    end type barostat_t

    !> No barostat: every hook does nothing (constant volume).
    type, extends(barostat_t), public :: barostat_none_t
    contains
        procedure :: active => none_active
    end type barostat_none_t

    public :: internal_pressure, kinetic_diagonal, pressure_diagonal, exchange_reals, exchange_iso_aniso

contains

    subroutine baro_init(self, p)
        class(barostat_t), intent(inout) :: self
        type(barostat_params_t), intent(in) :: p
        self%p = p
        self%p0 = p%pressure/p%nktv2p
        self%beta = p%compressibility*p%nktv2p
        self%tau = p%damping
        self%kt = p%boltz*p%temperature
        call self%setup(p)
    end subroutine baro_init

    !> A style's own set-up from its parameters (nothing by default).
    subroutine baro_setup(self, p)
        class(barostat_t), intent(inout) :: self
        type(barostat_params_t), intent(in) :: p
    end subroutine baro_setup

    !> The thermostat's present target temperature (k T, energy) becomes the barostat's: the Monte
    !> Carlo acceptance, C-rescale's noise and k T / V, MTTK's masses and chain all use self%kt.
    subroutine baro_follow(self, kt)
        class(barostat_t), intent(inout) :: self
        real(dp), intent(in) :: kt
        if (kt == self%kt) return
        self%kt = kt
        call self%retarget()
    end subroutine baro_follow

    !> What a style derives from k T, set again after it changed (nothing by default).
    subroutine baro_retarget(self)
        class(barostat_t), intent(inout) :: self
    end subroutine baro_retarget

    logical function baro_active(self)
        class(barostat_t), intent(in) :: self
        baro_active = .true.
    end function baro_active

    logical function none_active(self)
        class(barostat_none_t), intent(in) :: self
        none_active = .false.
    end function none_active

    !> Whether the force pass of this step must give the energy and the virial: by default at every
    !> step of an active barostat (one that reads the pressure at each step: C-rescale, MTTK).
    logical function baro_needs_virial(self, step)
        class(barostat_t), intent(in) :: self
        integer(i8), intent(in) :: step
        baro_needs_virial = self%active()
    end function baro_needs_virial

    !> The hooks that may change the box (nothing by default; moved: the neighbour list was rebuilt
    !> at the present positions after a change of the box, otherwise the integrator decides a build
    !> or refreshes the ghosts):
    !>   before_forces  after the drift of step `step`, before its force pass
    !>   after_step     after the second half kick of step `step`; it leaves the velocities as they
    !>                  are (a thermostat carries their kinetic energy past it: CSVR)
    !>   apply_event    energy stepping: the event of index `step` (at time step interval), all atoms
    !>                  drifted there
    subroutine baro_box_kept(self, eng, step, moved)
        class(barostat_t), intent(inout) :: self
        include 'barostat_hook_args.inc'
        moved = .false.
    end subroutine baro_box_kept

    !> Does the style replace velocity Verlet's half kicks and drift (first_half, second_half)?
    logical function baro_replaces_kicks(self)
        class(barostat_t), intent(in) :: self
        baro_replaces_kicks = .false.
    end function baro_replaces_kicks

    !> A style's first half kick and drift, or its second half kick (replaces_kicks); dtfm(type) =
    !> dt/2 ftm2v/m, dtf = dt/2 ftm2v (nothing by default).
    subroutine baro_half(self, eng, dtfm, dtf, dt, step)
        class(barostat_t), intent(inout) :: self
        type(engine_t), intent(inout) :: eng
        real(dp), intent(in) :: dtfm(:), dtf, dt
        integer(i8), intent(in) :: step
    end subroutine baro_half

    !> Energy held by the barostat's own variables, a term of the conserved quantity (0 by default).
    real(dp) function baro_energy(self, eng)
        class(barostat_t), intent(in) :: self
        type(engine_t), intent(in) :: eng
        baro_energy = 0
    end function baro_energy

    !> P0 V, the enthalpy's term (energy).
    real(dp) function baro_pv(self, eng)
        class(barostat_t), intent(in) :: self
        type(engine_t), intent(in) :: eng
        baro_pv = self%p0*eng%box%volume()
    end function baro_pv

    !> x(1), x(2), ... under prefix//'1', prefix//'2', ..., written (saving) or read back (ok false
    !> when one is missing): an array of a style's variables in exchange_own.
    subroutine exchange_reals(values, prefix, x, saving, ok)
        type(named_values_t), intent(inout) :: values
        character(len=*), intent(in) :: prefix
        real(dp), intent(inout) :: x(:)
        logical, intent(in) :: saving
        logical, intent(inout) :: ok
        if (saving) then
            call values%put_reals(prefix, x)
        else
            call values%get_reals(prefix, x, ok)
        end if
    end subroutine exchange_reals

    !> A variable of the box's motion that is one number with couple = 'iso' (x, under name) and one
    !> per edge with 'aniso' (x_axis, under prefix_axis//'1', ...), written (saving) or read back.
    subroutine exchange_iso_aniso(values, aniso, name, x, prefix_axis, x_axis, saving, ok)
        type(named_values_t), intent(inout) :: values
        logical, intent(in) :: aniso, saving
        character(len=*), intent(in) :: name, prefix_axis
        real(dp), intent(inout) :: x, x_axis(:)
        logical, intent(inout) :: ok
        if (aniso) then
            call exchange_reals(values, prefix_axis, x_axis, saving, ok)
        else
            call values%exchange(name, x, saving, ok)
        end if
    end subroutine exchange_iso_aniso

    !> The instantaneous pressure (energy/volume) from the kinetic energy and the last virial:
    !> (2 K + W) / (d V). Collective (the kinetic energy's sum).
    real(dp) function internal_pressure(eng) result(p)
        type(engine_t), intent(inout) :: eng
        p = (2*kinetic_energy(eng%atoms, eng%units) + eng%virial)/(eng%box%dimension*eng%box%volume())
    end function internal_pressure

    !> (K_xx, K_yy, K_zz), K_aa = mvv2e/2 sum m v_a^2 over every rank's atoms. Collective.
    function kinetic_diagonal(eng) result(k)
        type(engine_t), intent(in) :: eng
        real(dp) :: k(3)
        integer :: i
        k = 0
        do i = 1, eng%atoms%nlocal
            k = k + atom_mass(eng%atoms, i)*eng%atoms%v(:, i)**2
        end do
        call sum_all(k)
        k = 0.5_dp*eng%units%mvv2e*k
    end function kinetic_diagonal

    !> The diagonal of the instantaneous pressure tensor (energy/volume), P_aa = (2 K_aa + W_aa) / V,
    !> from the velocities and the last force pass's virial diagonal. Collective.
    function pressure_diagonal(eng) result(p)
        type(engine_t), intent(in) :: eng
        real(dp) :: p(3)
        p = (2*kinetic_diagonal(eng) + eng%virial_diag)/eng%box%volume()
    end function pressure_diagonal

end module terrace_barostat
