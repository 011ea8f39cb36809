!> Stochastic velocity rescaling (CSVR; Bussi, Donadio & Parrinello 2007): over a time s the total
!> kinetic energy K becomes
!>   K' = K + (1 - c)(K_T (R1^2 + S) / Nf - K) + 2 R1 sqrt(c (1 - c) K K_T / Nf),
!>   c = exp(-s / damping), K_T = Nf k_B T / 2, R1 normal, S chi-square(Nf - 1); v <- v sqrt(K'/K),
!> the exact solution of the kinetic-energy SDE over s. One global draw (every rank draws the same
!> numbers, keyed by the event index), then a uniform rescale of the owned velocities.
!> Velocity Verlet: over dt/2 before the first and after the second half kick (events 2 step and
!> 2 step + 1). The second half's K' is carried to the next step's first half, which then needs no
!> sum of its own (nothing else changes the velocities in between: a barostat's after_step leaves
!> them; zero_momentum says so through velocities_changed): one global sum per step. Energy stepping: at the
!> multiples of `interval`, as calendar events (the n-th keyed by n). A zero total momentum stays
!> zero: dof = d N - d.
module terrace_thermostat_csvr
    use terrace_kinds, only: dp, i8
    use terrace_atoms, only: atoms_t
    use terrace_counter_rng, only: rng_stream, rng_stream_t
    use terrace_named_values, only: named_values_t
    use terrace_thermostat, only: interval_thermostat_t, thermostat_traits_t, total_ke, scale_velocities
    implicit none
    private

    integer, parameter :: stream_csvr = 102   !< the generator's stream for this thermostat

    !> Energy stepping: a rescaling at every multiple of interval (0: none), the n_rescale-th keyed
    !> by n_rescale.
    type, extends(interval_thermostat_t), public :: csvr_t
        !> velocity Verlet: the kinetic energy the last post_kick left, while `carried` (nothing has
        !> changed the velocities since), for the next pre_kick; in checkpoints
        real(dp) :: ke_carried = 0
        logical :: carried = .false.
    contains
        procedure, nopass :: style_traits => csvr_traits
        procedure :: default_interval => csvr_default_interval
        procedure :: half_step => csvr_apply
        procedure :: pre_kick => csvr_pre_kick
        procedure :: post_kick => csvr_post_kick
        procedure :: velocities_changed => csvr_velocities_changed
        procedure :: exchange_own => csvr_exchange
        procedure :: apply_event => csvr_apply_event
    end type csvr_t

contains

    !> A uniform rescale keeps a zero total momentum zero; with energy stepping, at intervals.
    pure type(thermostat_traits_t) function csvr_traits() result(t)
        t = thermostat_traits_t(holds_momentum=.true., event_note='rescaling at fixed intervals')
    end function csvr_traits

    !> Energy stepping: a rescaling every damping/10 unless &thermostat interval says otherwise.
    pure real(dp) function csvr_default_interval(self, damping) result(interval)
        class(csvr_t), intent(in) :: self
        real(dp), intent(in) :: damping
        interval = damping/10
    end function csvr_default_interval

    !> CSVR over a time span: one global kinetic-energy draw keyed by `event`, then a uniform
    !> rescale of the owned velocities (energy stepping's scheduled rescalings). Collective.
    subroutine csvr_apply(self, atoms, span, event, time)
        class(csvr_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        real(dp), intent(in) :: span, time
        integer(i8), intent(in) :: event
        real(dp) :: ke_new
        call csvr_rescale(self, atoms, total_ke(self, atoms), span, event, time, ke_new)
        self%carried = .false.
    end subroutine csvr_apply

    !> Velocity Verlet, dt/2 before the first half kick (event 2 step): from the kinetic energy the
    !> last post_kick left when it is carried, else from a global sum (collective then).
    subroutine csvr_pre_kick(self, atoms, dt, step, t_mid)
        class(csvr_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        real(dp), intent(in) :: dt, t_mid
        integer(i8), intent(in) :: step
        real(dp) :: ke, ke_new
        if (self%carried) then
            ke = self%ke_carried
        else
            ke = total_ke(self, atoms)
        end if
        call csvr_rescale(self, atoms, ke, 0.5_dp*dt, 2*step, t_mid, ke_new)
        self%carried = .false.
    end subroutine csvr_pre_kick

    !> Velocity Verlet, dt/2 after the second half kick (event 2 step + 1); the new kinetic energy
    !> is carried to the next pre_kick. Collective.
    subroutine csvr_post_kick(self, atoms, dt, step, t_mid)
        class(csvr_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        real(dp), intent(in) :: dt, t_mid
        integer(i8), intent(in) :: step
        call csvr_rescale(self, atoms, total_ke(self, atoms), 0.5_dp*dt, 2*step + 1, t_mid, self%ke_carried)
        self%carried = .true.
    end subroutine csvr_post_kick

    !> Something else changed the velocities: the next pre_kick sums them again.
    subroutine csvr_velocities_changed(self)
        class(csvr_t), intent(inout) :: self
        self%carried = .false.
    end subroutine csvr_velocities_changed

    !> Bussi's draw from kinetic energy ke (the same on every rank), the owned velocities scaled to
    !> it, the change added to ecouple; ke_new the kinetic energy after.
    subroutine csvr_rescale(self, atoms, ke, span, event, time, ke_new)
        class(csvr_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        real(dp), intent(in) :: ke, span, time
        integer(i8), intent(in) :: event
        real(dp), intent(out) :: ke_new
        ke_new = csvr_kinetic_energy(self, ke, span, event, time)
        if (ke > 0) call scale_velocities(atoms, sqrt(ke_new/ke))
        self%ecouple_global = self%ecouple_global + (ke_new - ke)
    end subroutine csvr_rescale

    !> The interval's state and the carried kinetic energy (a checkpoint without it: none carried).
    subroutine csvr_exchange(self, values, saving, ok)
        class(csvr_t), intent(inout) :: self
        include 'checkpointed_args.inc'
        call self%interval_thermostat_t%exchange_own(values, saving, ok)
        if (saving .or. values%has('ts_csvr_carried')) then
            call values%exchange('ts_csvr_carried', self%carried, saving, ok)
            call values%exchange('ts_csvr_ke', self%ke_carried, saving, ok)
        else
            self%carried = .false.
        end if
    end subroutine csvr_exchange

    !> The scheduled rescaling at time t: Bussi's propagator over one interval, keyed by its index
    !> (the same on every rank and after a restart); with zero_momentum the momentum is removed.
    subroutine csvr_apply_event(self, atoms, t)
        class(csvr_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        real(dp), intent(in) :: t
        call self%half_step(atoms, self%interval, self%n_rescale, t)
        self%n_rescale = self%n_rescale + 1
        call self%hold_momentum(atoms)
    end subroutine csvr_apply_event

    !> Bussi's resampled kinetic energy (see the module header).
    real(dp) function csvr_kinetic_energy(self, ke, span, event, time) result(ke_new)
        type(csvr_t), intent(in) :: self
        real(dp), intent(in) :: ke, span, time
        integer(i8), intent(in) :: event
        type(rng_stream_t) :: s
        real(dp) :: c, kt_target, r1, sn
        integer(i8) :: nf
        nf = nint(self%dof, i8)
        if (nf < 1 .or. ke <= 0) then
            ke_new = ke
            return
        end if
        c = exp(-span/self%damping)
        kt_target = 0.5_dp*nf*self%boltz*self%target(time)
        s = rng_stream(self%seed, stream_csvr, 0_i8, event)
        r1 = s%normal()
        sn = s%chi_square(nf - 1)
        ke_new = ke + (1 - c)*(kt_target*(r1*r1 + sn)/nf - ke) + 2*r1*sqrt(c*(1 - c)*ke*kt_target/nf)
        ke_new = max(ke_new, 0.0_dp)
    end function csvr_kinetic_energy

end module terrace_thermostat_csvr
