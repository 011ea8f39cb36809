!> Temperature control: the abstract thermostat that velocity Verlet and energy stepping call, and
!> what every style shares. The target temperature is ramped linearly,
!>   T(t) = T0 + (T1 - T0) min(t / t_ramp, 1).
!> A style is one type extending thermostat_t, in a file of its own (thermostat_langevin,
!> thermostat_csvr, thermostat_nose_hoover, thermostat_andersen); thermostat_factory maps a style
!> name to its type. The integrators call the hooks below and never ask which style they hold:
!>
!>   velocity Verlet, one step:   pre_kick (dt/2 before the first half kick: CSVR; Nose-Hoover
!>                                through its half_step)
!>                                kick_drift in place of the first half kick and drift, when
!>                                traits%replaces_kick_drift (Langevin's B A O A)
!>                                post_kick (after the second half kick: CSVR, Nose-Hoover, Andersen)
!>                                hold_momentum (zero_momentum: remove the total momentum)
!>   energy stepping, events:     event_time (the next thermostat event, the same on every rank),
!>                                apply_event (at that time: Andersen collisions, CSVR rescaling),
!>                                schedule (after a list build or at the start: per-atom times)
!>   both:                        active, dof, ecouple / fold, chain_energy, save / restore
!>
!> What a style is (whether it holds the total momentum, replaces Verlet's kick and drift, takes a
!> chain, collides atoms at exact times, how it acts with energy stepping) is data: the record
!> its style_traits() returns, kept in `traits` from init on.
!>
!> Every random number is drawn from the counter-based generator keyed by (seed, stream, atom id,
!> step or event), never by rank or by order of atoms: a run gives the same trajectory on any rank
!> count and continues bitwise after a restart.
!>
!> Each operator adds the kinetic energy it changed to ecouple (energy put in by the thermostat),
!> so that etotal - ecouple (econserve) measures the integrator's own error. Per-atom operators
!> keep a per-rank partial sum, folded into the global value (one sum) at samples and checkpoints.
module terrace_thermostat
    use terrace_kinds, only: dp, i8
    use terrace_atoms, only: atoms_t
    use terrace_velocities, only: momentum_and_mass, local_mv2
    use terrace_mpi_env, only: sum_all
    use terrace_named_values, only: named_values_t
    use terrace_checkpointed, only: checkpointed_t
    implicit none
    private

    !> What a thermostat is made from (the run's units already applied).
    type, public :: thermostat_params_t
        real(dp) :: temperature = 0, temperature_end = 0   !< target at time 0 and at ramp_time
        real(dp) :: ramp_time = 0                !< length of the ramp (0: none)
        real(dp) :: damping = 1                  !< relaxation time (Langevin 1/gamma, CSVR tau, NHC tau, Andersen 1/rate)
        integer :: chain_length = 3              !< Nose-Hoover chains
        integer(i8) :: seed = 1
        logical :: zero_momentum = .false.
        integer :: dimension = 3
        integer(i8) :: natoms = 0
        real(dp) :: boltz = 1, mvv2e = 1
        !> energy stepping: CSVR rescaling or Andersen's global variant at the multiples of this
        !> time (0: none; Andersen then collides atom by atom at exact times)
        real(dp) :: interval = 0
    end type thermostat_params_t

    !> What a style is and what the deck may ask of it.
    type, public :: thermostat_traits_t
        logical :: active = .true.                 !< .false.: no thermostat (NVE)
        logical :: holds_momentum = .false.        !< keeps a zero total momentum zero (dof less d)
        logical :: replaces_kick_drift = .false.   !< Verlet: kick_drift for the first half kick and drift
        logical :: takes_chain = .false.           !< takes &thermostat chain_length
        logical :: collides_atoms = .false.        !< atoms collide one by one at exact times (event-driven runs)
        !> with energy stepping, how the style acts (for messages; '': it cannot, its operators
        !> need the steps of velocity Verlet)
        character(len=32) :: event_note = ''
    end type thermostat_traits_t

    type, abstract, extends(checkpointed_t), public :: thermostat_t
        type(thermostat_traits_t) :: traits     !< the style's style_traits(), from init on
        real(dp) :: t_start = 0, t_end = 0      !< target temperature at time 0 and at run_time
        real(dp) :: run_time = 0                !< length of the ramp
        real(dp) :: damping = 1
        integer(i8) :: seed = 1
        logical :: zero_momentum = .false.
        integer :: dimension = 3
        real(dp) :: dof = 0                     !< degrees of freedom of the thermostatted kinetic energy
        real(dp) :: boltz = 1, mvv2e = 1
        real(dp) :: ecouple_global = 0          !< energy put in, the same on every rank
        real(dp) :: ecouple_local = 0           !< this rank's part not yet folded into ecouple_global
    contains
        procedure, non_overridable :: init => ts_init
        procedure :: setup => ts_setup
        procedure, nopass :: style_traits => ts_traits
        procedure, non_overridable :: active => ts_active
        procedure :: default_interval => ts_default_interval
        procedure, non_overridable :: target => ts_target
        procedure, non_overridable :: ecouple => ts_ecouple
        procedure, non_overridable :: fold => ts_fold
        procedure, non_overridable :: remove_momentum => ts_remove_momentum
        procedure, non_overridable :: hold_momentum => ts_hold_momentum
        procedure :: chain_energy => ts_chain_energy
        procedure, non_overridable :: save => ts_save
        procedure, non_overridable :: restore => ts_restore
        ! velocity Verlet
        procedure :: pre_kick => ts_pre_kick
        procedure :: kick_drift => ts_kick_drift
        procedure :: post_kick => ts_post_kick
        procedure :: half_step => ts_half_step
        procedure :: velocities_changed => ts_velocities_changed
        ! energy stepping
        procedure :: event_time => ts_event_time
        procedure :: apply_event => ts_at_time
        procedure :: schedule => ts_at_time
    end type thermostat_t

    !> A thermostat that may act at the multiples of an interval (energy stepping's calendar): the
    !> interval (0: none), the index of the next action (its draws keyed by it) and its time; the
    !> index goes into checkpoints.
    type, extends(thermostat_t), public :: interval_thermostat_t
        real(dp) :: interval = 0
        integer(i8) :: n_rescale = 1
    contains
        procedure :: setup => interval_setup
        procedure :: event_time => interval_event_time
        procedure :: exchange_own => interval_exchange
    end type interval_thermostat_t

    !> No thermostat: every hook does nothing (NVE).
    type, extends(thermostat_t), public :: thermostat_none_t
    contains
        procedure, nopass :: style_traits => none_traits
    end type thermostat_none_t

    public :: thermostat_dof, total_ke, scale_velocities

contains

    !> Degrees of freedom of the thermostatted kinetic energy: d N, less d when the total momentum
    !> is held (zero_momentum, or a style that keeps a zero total momentum zero: none, CSVR,
    !> Nose-Hoover; as LAMMPS for an unthermostatted run).
    pure real(dp) function thermostat_dof(holds_momentum, zero_momentum, dimension, natoms) result(dof)
        logical, intent(in) :: holds_momentum, zero_momentum
        integer, intent(in) :: dimension
        integer(i8), intent(in) :: natoms
        dof = real(dimension, dp)*real(natoms, dp)
        if (zero_momentum .or. holds_momentum) dof = dof - dimension
        dof = max(dof, 0.0_dp)
    end function thermostat_dof

    !> The state every style shares, then the style's own set-up.
    subroutine ts_init(self, p)
        class(thermostat_t), intent(inout) :: self
        type(thermostat_params_t), intent(in) :: p
        self%traits = self%style_traits()
        self%t_start = p%temperature; self%t_end = p%temperature_end; self%run_time = p%ramp_time
        self%damping = p%damping
        self%seed = p%seed; self%zero_momentum = p%zero_momentum
        self%dimension = p%dimension
        self%boltz = p%boltz; self%mvv2e = p%mvv2e
        self%dof = thermostat_dof(self%traits%holds_momentum, p%zero_momentum, p%dimension, p%natoms)
        self%ecouple_global = 0; self%ecouple_local = 0
        call self%setup(p)
    end subroutine ts_init

    subroutine ts_setup(self, p)
        class(thermostat_t), intent(inout) :: self
        type(thermostat_params_t), intent(in) :: p
    end subroutine ts_setup

    subroutine interval_setup(self, p)
        class(interval_thermostat_t), intent(inout) :: self
        type(thermostat_params_t), intent(in) :: p
        self%interval = p%interval
        self%n_rescale = 1
    end subroutine interval_setup

    !> The next action at a multiple of the interval (huge when none).
    pure real(dp) function interval_event_time(self) result(t)
        class(interval_thermostat_t), intent(in) :: self
        t = huge(1.0_dp)
        if (self%interval > 0) t = real(self%n_rescale, dp)*self%interval
    end function interval_event_time

    !> The index of the next action, with an interval.
    subroutine interval_exchange(self, values, saving, ok)
        class(interval_thermostat_t), intent(inout) :: self
        include 'checkpointed_args.inc'
        if (self%interval > 0) call values%exchange('ts_n_rescale', self%n_rescale, saving, ok)
    end subroutine interval_exchange

    !> A style's traits (a style overrides this with its own; the default: active, nothing else).
    pure type(thermostat_traits_t) function ts_traits() result(t)
        t = thermostat_traits_t()
    end function ts_traits

    !> No thermostat: nothing acts, and a zero total momentum stays zero.
    pure type(thermostat_traits_t) function none_traits() result(t)
        t = thermostat_traits_t(active=.false., holds_momentum=.true.)
    end function none_traits

    !> With energy stepping: the interval of the style's scheduled action when the deck gives none
    !> (0: none).
    pure real(dp) function ts_default_interval(self, damping) result(interval)
        class(thermostat_t), intent(in) :: self
        real(dp), intent(in) :: damping
        interval = 0
    end function ts_default_interval

    !> Is there a thermostat (traits%active)?
    pure logical function ts_active(self)
        class(thermostat_t), intent(in) :: self
        ts_active = self%traits%active
    end function ts_active

    !> Target temperature at time t (linear ramp from t_start at 0 to t_end at run_time).
    pure real(dp) function ts_target(self, t) result(temp)
        class(thermostat_t), intent(in) :: self
        real(dp), intent(in) :: t
        real(dp) :: f
        f = 0
        if (self%run_time > 0) f = min(max(t/self%run_time, 0.0_dp), 1.0_dp)
        temp = self%t_start + (self%t_end - self%t_start)*f
    end function ts_target

    !> Velocity Verlet's hooks around the kicks of step `step` (spanning ((step - 1) dt, step dt],
    !> t_mid its middle): by default the style's half_step over dt/2 before the first half kick
    !> (its draws keyed by the event 2 step) and after the second (event 2 step + 1). A style that
    !> acts otherwise overrides the hook itself (Andersen's post_kick).
    subroutine ts_pre_kick(self, atoms, dt, step, t_mid)
        class(thermostat_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        real(dp), intent(in) :: dt, t_mid
        integer(i8), intent(in) :: step
        call self%half_step(atoms, 0.5_dp*dt, 2*step, t_mid)
    end subroutine ts_pre_kick

    subroutine ts_post_kick(self, atoms, dt, step, t_mid)
        class(thermostat_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        real(dp), intent(in) :: dt, t_mid
        integer(i8), intent(in) :: step
        call self%half_step(atoms, 0.5_dp*dt, 2*step + 1, t_mid)
    end subroutine ts_post_kick

    !> Velocity Verlet: something other than the thermostat changed the velocities since post_kick
    !> (remove_momentum, for zero_momentum); a style that carries a sum from post_kick to the next
    !> pre_kick drops it (CSVR). Nothing by default.
    subroutine ts_velocities_changed(self)
        class(thermostat_t), intent(inout) :: self
    end subroutine ts_velocities_changed

    !> The style's operator over a span of time (half a step) at time `time`, its random draws
    !> keyed by `event` (nothing by default; CSVR, Nose-Hoover).
    subroutine ts_half_step(self, atoms, span, event, time)
        class(thermostat_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        real(dp), intent(in) :: span, time
        integer(i8), intent(in) :: event
    end subroutine ts_half_step

    !> The first half kick and the drift, for a style that replaces them (traits%replaces_kick_drift);
    !> dtfm(type) = dt/2 ftm2v/m.
    subroutine ts_kick_drift(self, atoms, dtfm, dt, step, t_mid)
        class(thermostat_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        real(dp), intent(in) :: dtfm(:), dt, t_mid
        integer(i8), intent(in) :: step
    end subroutine ts_kick_drift

    !> Energy stepping: the time of the next thermostat event (huge when none), the same on every rank.
    pure real(dp) function ts_event_time(self) result(t)
        class(thermostat_t), intent(in) :: self
        t = huge(1.0_dp)
    end function ts_event_time

    !> Energy stepping: the event at time t (apply_event), or the per-atom schedule after the atoms
    !> were reordered or moved between ranks (schedule). Collective where a style's are.
    subroutine ts_at_time(self, atoms, t)
        class(thermostat_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        real(dp), intent(in) :: t
    end subroutine ts_at_time

    !> Energy held by the thermostat's own variables at time t (Nose-Hoover chains; 0 otherwise).
    pure real(dp) function ts_chain_energy(self, time) result(e)
        class(thermostat_t), intent(in) :: self
        real(dp), intent(in) :: time
        e = 0
    end function ts_chain_energy

    !> The thermostat's state for a checkpoint: ecouple (folded: collective), then the style's own
    !> (exchange_own).
    subroutine ts_save(self, values)
        class(thermostat_t), intent(inout) :: self
        type(named_values_t), intent(inout) :: values
        real(dp) :: e
        logical :: ok
        e = self%ecouple()
        call values%put('ts_ecouple', e)
        ok = .true.
        call self%exchange_own(values, .true., ok)
    end subroutine ts_save

    !> The state ts_save wrote (ok false when some of it is missing).
    subroutine ts_restore(self, values, ok)
        class(thermostat_t), intent(inout) :: self
        type(named_values_t), intent(inout) :: values
        logical, intent(inout) :: ok
        self%ecouple_global = values%get_r('ts_ecouple', ok)
        self%ecouple_local = 0
        call self%exchange_own(values, .false., ok)
    end subroutine ts_restore

    !> Global kinetic energy (collective). One type (the common case): m sum v^2 over the contiguous
    !> velocities, a loop that vectorises; otherwise the sum of m v^2 that kinetic_energy takes.
    real(dp) function total_ke(self, atoms) result(ke)
        class(thermostat_t), intent(in) :: self
        type(atoms_t), intent(in) :: atoms
        if (.not. atoms%per_atom_mass .and. atoms%ntypes == 1) then
            ke = atoms%mass(1)*sum_of_squares(3*atoms%nlocal, atoms%v)
        else
            ke = local_mv2(atoms)
        end if
        call sum_all(ke)
        ke = 0.5_dp*self%mvv2e*ke
    end function total_ke

    subroutine scale_velocities(atoms, alpha)
        type(atoms_t), intent(inout) :: atoms
        real(dp), intent(in) :: alpha
        call scale_run(3*atoms%nlocal, atoms%v, alpha)
    end subroutine scale_velocities

    !> v = alpha v over the owned atoms' velocities as one contiguous run (v(3, nlocal) passed as
    !> v(3 nlocal): a loop GCC vectorises, where v(:, i) of the derived type has a stride it cannot see).
    pure subroutine scale_run(n, v, alpha)
        integer, intent(in) :: n
        real(dp), intent(inout) :: v(n)
        real(dp), intent(in) :: alpha
        v = alpha*v
    end subroutine scale_run

    !> The sum of v(k)^2 over one contiguous run, in eight partial sums (a vector of them; a single
    !> running sum waits for each add), summed at the end.
    pure real(dp) function sum_of_squares(n, v) result(s)
        integer, intent(in) :: n
        real(dp), intent(in) :: v(n)
        real(dp) :: part(8)
        integer :: k, m
        part = 0
        m = (n/8)*8
        do k = 1, m, 8
            part = part + v(k:k + 7)**2
        end do
        s = sum(part)
        do k = m + 1, n
            s = s + v(k)**2
        end do
    end function sum_of_squares

    !> Remove the total momentum (collective); its kinetic energy P^2/2M goes to ecouple.
    subroutine ts_remove_momentum(self, atoms)
        class(thermostat_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        real(dp) :: p(4), vc(3)
        integer :: i
        p = momentum_and_mass(atoms)
        if (p(4) <= 0) return
        vc = p(1:3)/p(4)
        do i = 1, atoms%nlocal
            atoms%v(:, i) = atoms%v(:, i) - vc
        end do
        self%ecouple_global = self%ecouple_global - 0.5_dp*self%mvv2e*sum(p(1:3)*vc)
        call self%velocities_changed()
    end subroutine ts_remove_momentum

    !> With zero_momentum: remove the total momentum (collective); otherwise nothing.
    subroutine ts_hold_momentum(self, atoms)
        class(thermostat_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        if (self%zero_momentum) call self%remove_momentum(atoms)
    end subroutine ts_hold_momentum

    !> The energy put in so far (collective: folds every rank's partial sum into the global value).
    real(dp) function ts_ecouple(self) result(e)
        class(thermostat_t), intent(inout) :: self
        call self%fold()
        e = self%ecouple_global
    end function ts_ecouple

    !> Fold every rank's partial sum of ecouple into the global value (collective).
    subroutine ts_fold(self)
        class(thermostat_t), intent(inout) :: self
        real(dp) :: part
        part = self%ecouple_local
        call sum_all(part)
        self%ecouple_global = self%ecouple_global + part
        self%ecouple_local = 0
    end subroutine ts_fold

end module terrace_thermostat
