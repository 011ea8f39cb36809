!> The run's assembly: from the validated deck (config_t) to the small records of parameters that
!> the engine, the integrators, the run control and the thermostat are made from. Only this layer
!> (and the deck reader below it) knows config_t: nothing under engine/, integrators/, thermostat/
!> or lower names it.
module terrace_run_params
    use terrace_kinds, only: dp, i8
    use terrace_config, only: config_t
    use terrace_namelist_text, only: deck_hash
    use terrace_engine, only: engine_params_t
    use terrace_run_control, only: control_params_t
    use terrace_schedule, only: schedule_t
    use terrace_velocity_verlet, only: verlet_params_t
    use terrace_energy_stepping, only: es_params_t
    use terrace_event_driven, only: ed_params_t
    use terrace_thermostat, only: thermostat_t, thermostat_params_t
    use terrace_thermostat_factory, only: new_thermostat
    use terrace_barostat, only: barostat_t, barostat_params_t
    use terrace_barostat_factory, only: new_barostat
    use terrace_minimize, only: minimize_params_t
    implicit none
    private

    public :: engine_params, control_params, verlet_params, es_params, ed_params, make_thermostat, make_barostat, &
              minimize_params

contains

    type(engine_params_t) function engine_params(cfg) result(p)
        type(config_t), intent(in) :: cfg
        p%units = cfg%units
        p%dimension = cfg%dimension
        p%skin = cfg%skin
        p%outer_skin = cfg%outer_skin
        p%prune_every = cfg%prune_every
        p%list_every = cfg%list_every
        p%list_check = cfg%list_check
        p%straight_lines = cfg%integ_style%exact_time
        p%virial_diagonal = cfg%barostat_couple == 'aniso'      ! (only a barostat takes couple)
    end function engine_params

    !> Checkpoints and stops: steps between checkpoints for velocity Verlet (checkpoint_every, or
    !> checkpoint_interval / dt), a time for energy stepping and event-driven runs.
    type(control_params_t) function control_params(cfg) result(p)
        type(config_t), intent(in) :: cfg
        p%checkpoint_file = trim(cfg%checkpoint_file)
        if (.not. cfg%integ_style%time_stepped) then      ! energy stepping, event-driven: by time
            if (cfg%checkpoint_interval > 0) p%interval = cfg%checkpoint_interval
        else
            if (cfg%checkpoint_every > 0) p%every = cfg%checkpoint_every
            if (cfg%checkpoint_interval > 0) p%every = max(1_i8, nint(cfg%checkpoint_interval/cfg%dt, i8))
        end if
        if (cfg%walltime_limit > 0) p%walltime_limit = cfg%walltime_limit
        p%restart_from = trim(cfg%read_checkpoint)
        p%integrator = trim(cfg%integrator)
        p%deck_path = cfg%path
        p%deck_hash = deck_hash(cfg%nml)
        p%seed = cfg%seed
        p%dimension = cfg%dimension
        p%skin = cfg%skin
        p%outer_skin = cfg%outer_skin
        p%buffer_drift = cfg%buffer_drift
        p%buffer_temperature = cfg%buffer_temperature
    end function control_params

    type(verlet_params_t) function verlet_params(cfg) result(p)
        type(config_t), intent(in) :: cfg
        p%dt = cfg%dt
        p%restart_from = trim(cfg%read_checkpoint)
    end function verlet_params

    type(es_params_t) function es_params(cfg) result(p)
        type(config_t), intent(in) :: cfg
        p%terrace_height = cfg%terrace_height
        p%target_mean_dt = cfg%target_mean_dt
        p%root_tolerance = cfg%root_tolerance
        p%restart_from = trim(cfg%read_checkpoint)
        p%where_height = cfg%where('integrator', 'terrace_height')
        p%where_mean_dt = cfg%where('integrator', 'target_mean_dt')
    end function es_params

    !> Event-driven dynamics: until run_time, thermo samples every thermo_interval (default
    !> run_time / 10), frames every trajectory_interval (default: at the samples; none without a
    !> trajectory file).
    type(ed_params_t) function ed_params(cfg) result(p)
        type(config_t), intent(in) :: cfg
        p%t_end = cfg%run_time
        p%sample_dt = cfg%run_time/10
        if (cfg%thermo_interval > 0) p%sample_dt = cfg%thermo_interval
        p%frame_dt = 0
        if (len_trim(cfg%trajectory_file) > 0) then
            p%frame_dt = p%sample_dt
            if (cfg%trajectory_interval > 0) p%frame_dt = cfg%trajectory_interval
        end if
        p%temperature = cfg%temperature
        p%seed = cfg%seed
        p%reverse_velocities = cfg%reverse_velocities
        p%where_cells = cfg%where('system', 'cells')
        p%restart_from = trim(cfg%read_checkpoint)
    end function ed_params

    !> The deck's thermostat ('none': one that does nothing) for natoms atoms; its temperature ramp
    !> runs over the schedule's length (Verlet: n_steps dt; energy stepping: run_time, if given).
    !> Energy stepping's scheduled variants (CSVR, Andersen's global one) act at &thermostat interval.
    subroutine make_thermostat(cfg, natoms, sched, ts)
        type(config_t), intent(in) :: cfg
        integer(i8), intent(in) :: natoms
        type(schedule_t), intent(in) :: sched
        class(thermostat_t), allocatable, intent(out) :: ts
        type(thermostat_params_t) :: p
        p%temperature = cfg%thermostat_temperature
        p%temperature_end = cfg%thermostat_temperature_end
        if (cfg%integ_style%exact_time) then
            p%ramp_time = merge(sched%t_end, 0.0_dp, sched%t_end < huge(1.0_dp))
            if (cfg%thermostat_interval > 0) p%interval = cfg%thermostat_interval
        else if (cfg%integ_style%event_driven) then
            p%ramp_time = cfg%run_time
        else
            p%ramp_time = sched%n_steps*cfg%dt
        end if
        p%damping = cfg%thermostat_damping
        p%chain_length = cfg%chain_length
        p%seed = cfg%thermostat_seed
        p%zero_momentum = cfg%zero_momentum
        p%dimension = cfg%dimension
        p%natoms = natoms
        p%boltz = cfg%units%boltz
        p%mvv2e = cfg%units%mvv2e
        call new_thermostat(cfg%thermostat, p, ts)
    end subroutine make_thermostat

    !> The deck's barostat ('none': one that does nothing) for natoms atoms, at the thermostat's
    !> temperature.
    subroutine make_barostat(cfg, natoms, bs)
        type(config_t), intent(in) :: cfg
        integer(i8), intent(in) :: natoms
        class(barostat_t), allocatable, intent(out) :: bs
        type(barostat_params_t) :: p
        p%pressure = cfg%barostat_pressure
        if (cfg%barostat_damping > 0) p%damping = cfg%barostat_damping
        if (cfg%barostat_compressibility > 0) p%compressibility = cfg%barostat_compressibility
        p%temperature = cfg%thermostat_temperature
        p%dt = cfg%dt
        p%seed = cfg%thermostat_seed
        p%natoms = natoms
        p%dimension = cfg%dimension
        p%aniso = cfg%barostat_couple == 'aniso'
        p%boltz = cfg%units%boltz
        p%nktv2p = cfg%units%nktv2p
        if (cfg%integ_style%exact_time .and. cfg%barostat_interval > 0) p%interval = cfg%barostat_interval
        call new_barostat(cfg%barostat, p, bs)
    end subroutine make_barostat

    !> The deck's minimization (FIRE's first step: &integrator dt when given, else 0.001 ps in
    !> metal units and 0.005 tau otherwise; dmax 0.1 length units, as LAMMPS).
    type(minimize_params_t) function minimize_params(cfg) result(p)
        type(config_t), intent(in) :: cfg
        p%style = cfg%minimize
        p%etol = cfg%etol
        p%ftol = cfg%ftol
        p%max_iterations = cfg%max_iterations
        p%max_evaluations = cfg%max_evaluations
        p%dt = merge(0.001_dp, 0.005_dp, cfg%units%name == 'metal')
        if (cfg%dt > 0) p%dt = cfg%dt
        p%dmax = 0.1_dp
        p%box_relax = cfg%box_relax
        p%pressure = cfg%min_pressure
    end function minimize_params

end module terrace_run_params
