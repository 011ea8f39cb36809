!> Monte Carlo barostat (as OpenMM's MonteCarloBarostat): every `every` steps (energy stepping: at
!> the multiples of `interval`, a calendar entry, all atoms drifted to that time) an isotropic trial
!> change of the volume, V' = V + dV_max (2 u - 1), scales the box and the atom positions (not the
!> velocities); its energy U' is computed and the move accepted with probability
!>   min(1, exp(-(U' - U + P0 (V' - V) - N k T ln(V'/V)) / k T)),
!> the Metropolis rule on the enthalpy H = U + P V - N k T ln V. A rejected move restores the
!> engine's saved state exactly (atoms, lists, domain, box, energy, forces). dV_max starts at 1 %
!> of the volume and is adapted every 10 trials to keep the acceptance between 25 % and 75 %
!> (times 1.1 or 1/1.1, at most a third of the volume). The uniform number is drawn from the
!> counter-based generator keyed by (seed, step): the same on every rank.
!> couple = 'aniso' (as OpenMM's MonteCarloAnisotropicBarostat): each trial changes the volume by
!> the same rule through one edge, drawn at random among the d (a third number of the same stream),
!> the other edges kept; the acceptance rule is unchanged (the ensemble's measure dL_x dL_y dL_z
!> with V^N from the scaled positions: a move uniform in V along one edge is uniform in that edge).
module terrace_barostat_mc
    use terrace_kinds, only: dp, i8
    use terrace_engine, only: engine_t, engine_state_t
    use terrace_barostat, only: barostat_t, barostat_params_t
    use terrace_counter_rng, only: rng_stream, rng_stream_t
    use terrace_named_values, only: named_values_t
    implicit none
    private

    integer, parameter :: stream_mc_barostat = 201   !< the generator's stream for this barostat

    type, extends(barostat_t), public :: mc_barostat_t
        real(dp) :: dv_max = -1                  !< < 0: not yet set (1 % of the first volume)
        integer(i8) :: attempted = 0, accepted = 0   !< since the last adaptation
        integer(i8) :: total_attempted = 0, total_accepted = 0
        type(engine_state_t) :: saved
    contains
        procedure :: needs_virial => mc_needs_virial
        procedure :: after_step => mc_after_step
        procedure :: apply_event => mc_trial
        procedure :: exchange_own => mc_exchange
    end type mc_barostat_t

contains

    !> The step of a trial needs the energy of the state it starts from.
    logical function mc_needs_virial(self, step)
        class(mc_barostat_t), intent(in) :: self
        integer(i8), intent(in) :: step
        mc_needs_virial = mod(step, int(self%p%every, i8)) == 0
    end function mc_needs_virial

    subroutine mc_after_step(self, eng, step, moved)
        class(mc_barostat_t), intent(inout) :: self
        include 'barostat_hook_args.inc'
        moved = .false.
        if (mod(step, int(self%p%every, i8)) /= 0) return
        call mc_trial(self, eng, step, moved)
    end subroutine mc_after_step

    !> One trial move from the present state (eng%pe its energy), its numbers keyed by `step`: velocity
    !> Verlet's step (after_step), or energy stepping's event of index `step` (apply_event: a trial at
    !> every event).
    subroutine mc_trial(self, eng, step, moved)
        class(mc_barostat_t), intent(inout) :: self
        include 'barostat_hook_args.inc'
        type(rng_stream_t) :: s
        real(dp) :: v, v_new, u_old, dh, mu, ua, ub, scale(3)
        integer :: d, axis
        moved = .false.
        v = eng%box%volume()
        if (self%dv_max < 0) self%dv_max = 0.01_dp*v
        s = rng_stream(self%p%seed, stream_mc_barostat, 0_i8, step)
        ua = s%uniform()
        ub = s%uniform()
        axis = 0
        if (self%p%aniso) axis = min(1 + int(self%p%dimension*s%uniform()), self%p%dimension)
        v_new = v + self%dv_max*(2*ua - 1)
        if (v_new <= 0) return
        u_old = eng%pe
        call eng%save_state(self%saved)
        if (axis > 0) then
            scale = 1
            scale(axis) = v_new/v
        else
            mu = (v_new/v)**(1.0_dp/self%p%dimension)
            scale = [(merge(mu, 1.0_dp, d <= self%p%dimension), d = 1, 3)]
        end if
        call eng%scale_box(scale, velocities=.false.)
        call eng%compute_forces(.true.)
        dh = eng%pe - u_old + self%p0*(v_new - v) - self%p%natoms*self%kt*log(v_new/v)
        self%attempted = self%attempted + 1
        self%total_attempted = self%total_attempted + 1
        if (dh <= 0 .or. ub < exp(-dh/self%kt)) then
            self%accepted = self%accepted + 1
            self%total_accepted = self%total_accepted + 1
            moved = .true.
        else
            call eng%restore_state(self%saved)
        end if
        if (self%attempted >= 10) then
            if (self%accepted < 0.25_dp*self%attempted) then
                self%dv_max = self%dv_max/1.1_dp
            else if (self%accepted > 0.75_dp*self%attempted) then
                self%dv_max = min(self%dv_max*1.1_dp, v/3)
            end if
            self%attempted = 0; self%accepted = 0
        end if
    end subroutine mc_trial

    !> The trial size and the acceptance counts.
    subroutine mc_exchange(self, values, saving, ok)
        class(mc_barostat_t), intent(inout) :: self
        include 'checkpointed_args.inc'
        call values%exchange('baro_dv_max', self%dv_max, saving, ok)
        call values%exchange('baro_attempted', self%attempted, saving, ok)
        call values%exchange('baro_accepted', self%accepted, saving, ok)
        call values%exchange('baro_total_attempted', self%total_attempted, saving, ok)
        call values%exchange('baro_total_accepted', self%total_accepted, saving, ok)
    end subroutine mc_exchange

end module terrace_barostat_mc
