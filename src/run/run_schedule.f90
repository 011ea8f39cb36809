!> The run's schedule from the deck (terrace_schedule holds it; both integrators read it).
module terrace_run_schedule
    use terrace_kinds, only: dp, i8
    use terrace_config, only: config_t
    use terrace_schedule, only: schedule_t
    use terrace_text, only: style_row
    use terrace_integrator_styles, only: integrator_style_t, integrator_table
    implicit none
    private

    public :: make_schedule

contains

    !> The schedule of the deck's integrator.
    function make_schedule(cfg) result(s)
        type(config_t), intent(in) :: cfg
        type(schedule_t) :: s
        type(integrator_style_t) :: integ
        integ = integrator_table(style_row(integrator_table%name, cfg%integrator))
        if (integ%exact_time) then          ! by time
            if (cfg%run_time > 0) s%t_end = cfg%run_time
            s%n_steps = huge(1_i8)
            if (cfg%n_steps >= 0) s%n_steps = cfg%n_steps
            if (cfg%thermo_every > 0) then
                s%thermo_every = cfg%thermo_every
            else if (cfg%thermo_interval > 0) then
                s%thermo_interval = cfg%thermo_interval
            else if (cfg%run_time > 0) then
                s%thermo_interval = cfg%run_time/10
            else
                s%thermo_every = max(1_i8, s%n_steps/10)
            end if
            s%traj_every = max(0_i8, cfg%trajectory_every)
            s%traj_interval = max(0.0_dp, cfg%trajectory_interval)
            if (s%traj_every == 0 .and. .not. s%traj_interval > 0) then
                s%traj_every = s%thermo_every; s%traj_interval = s%thermo_interval
            end if
        else
            s%n_steps = cfg%n_steps
            if (s%n_steps < 0) s%n_steps = max(1_i8, nint(cfg%run_time/cfg%dt, i8))
            if (cfg%thermo_every > 0) then
                s%thermo_every = cfg%thermo_every
            else if (cfg%thermo_interval > 0) then
                s%thermo_every = max(1_i8, nint(cfg%thermo_interval/cfg%dt, i8))
            else
                s%thermo_every = max(1_i8, s%n_steps/10)
            end if
            s%traj_every = 0
            if (cfg%trajectory_every > 0) s%traj_every = cfg%trajectory_every
            if (cfg%trajectory_interval > 0) s%traj_every = max(1_i8, nint(cfg%trajectory_interval/cfg%dt, i8))
            if (cfg%trajectory_every <= 0 .and. .not. cfg%trajectory_interval > 0) s%traj_every = s%thermo_every
        end if
        if (integ%exact_time) then
            s%covered = merge(s%t_end, 0.0_dp, cfg%run_time > 0)
        else
            s%covered = s%n_steps*cfg%dt
        end if
        if (len_trim(cfg%trajectory_file) == 0) then
            s%traj_every = 0; s%traj_interval = 0
        end if
    end function make_schedule

end module terrace_run_schedule
