!> Energy stepping (Gonzalez, Schmidt & Ortiz): the exact solution of the terraced Lagrangian
!> L_h = K - V_h, V_h = h floor(V/h), V the total potential energy of all atoms on all ranks.
!>
!> Between level crossings nothing acts: every atom (owned and ghost) moves in a straight line.
!> At a crossing of a terrace edge the velocities jump along the gradient g = grad V:
!>   v_i += lambda g_i / m_i,  a = sum |g_i|^2/m_i,  b = sum g_i . v_i  (times mvv2e),
!>   climbing (b > 0, b^2 >= 2 a h):  lambda = -2h / (b + sqrt(b^2 - 2 a h)),   k -> k + 1
!>   too slow to climb:               lambda = -2b / a  (reflection),            k unchanged
!>   falling (b < 0):                 lambda = -2h / (|b| + sqrt(b^2 + 2 a h)),  k -> k - 1
!> so that K + k h is conserved to round-off (the nominal rise +-h, never the measured V
!> difference). After a kick the edge the state sits on is moved to the measured V, so that the
!> next search cannot find it again at s = 0+.
!>
!> The step is the global minimum of the next level crossing, the exact neighbour-list expiry
!> (straight lines: a quadratic per atom), the next sample time and the end of the run: one
!> MPI_Allreduce(MIN) per event; the crossing search (event_solver) costs one global sum of
!> (V, V', V'', W) per ray evaluation; samples are written at exactly the requested times.
!> Checkpoints (&output checkpoint_interval) are window ends too, with a forced neighbour-list build
!> (cell lists), and hold the whole event-loop state (terrace index, edges, the solver's last
!> values at the search origin, counters, next sample times), so a restart continues bitwise.
!>
!> With an Andersen thermostat (terrace_thermostat) each atom's next collision time (a Poisson
!> process of rate 1/damping, a function of seed, atom id and time only) is one more candidate of
!> the window minimum: at the earliest one the colliding atom gets a fresh Maxwell-Boltzmann
!> velocity, the terrace index and edges stay as they are (V is continuous), the ghosts' velocities
!> are re-synchronised and the search restarts from a ray pass at the collision point (V' and V''
!> along the new velocities); with zero_momentum the total momentum is removed after each collision.
!> Thermo gains ecouple and econserve = K + k h - ecouple.
module terrace_energy_stepping
    use terrace_kinds, only: dp, i8
    use terrace_engine, only: engine_t
    use terrace_event_solver, only: ray_t, event_solver_t, crossing_t, level_upper, level_lower
    use terrace_thermo, only: thermo_writer_t
    use terrace_observables, only: thermo_sample_t
    use terrace_trajectory, only: trajectory_t
    use terrace_timers, only: t_output
    use terrace_mpi_env, only: world, sum_all, min_all
    use terrace_errors, only: stop_all, check_all
    use terrace_run_checks, only: energy_guard_t
    use terrace_velocities, only: kinetic_energy
    use terrace_jump, only: terrace_jump_lambda, jump_climb, jump_reflect, jump_fall, jump_none
    use terrace_run_control, only: run_control_t
    use terrace_checkpoint, only: ckpt_values_t
    use terrace_scene_plan, only: pair_cells
    use terrace_thermostat, only: thermostat_t, thermostat_andersen
    use, intrinsic :: iso_fortran_env, only: output_unit
    implicit none
    private

    !> The engine seen as a ray for the event solver: s is measured from the search origin,
    !> where the atoms are.
    type, extends(ray_t) :: engine_ray_t
        type(engine_t), pointer :: eng => null()
        real(dp) :: last_s = -huge(1.0_dp)
        real(dp) :: last_out(4) = 0
    contains
        procedure :: eval_ray => engine_ray_eval
    end type engine_ray_t

    type, public :: es_stats_t
        integer(i8) :: events = 0, reflections = 0, ups = 0, downs = 0
        integer(i8) :: ray_evals = 0, force_passes = 0, verify_misses = 0, rebuilds = 0
        real(dp) :: time = 0
    end type es_stats_t

    character(len=*), parameter, public :: es_thermo_header = &
        ',events,reflections,mean_dt,evals_per_event,terrace_height,e_terraced'

    public :: run_energy_stepping, choose_terrace_height, print_es_estimates

contains

    subroutine engine_ray_eval(self, s, fdc)
        class(engine_ray_t), intent(inout) :: self
        real(dp), intent(in) :: s
        real(dp), intent(out) :: fdc(3)
        call self%eng%ray_pass(s, self%last_out)
        self%last_s = s
        fdc = self%last_out(1:3)
        if (self%evals > 100000) then
            ! a search that does not converge: show where it is, then stop every rank (collective:
            ! every rank makes the same decisions from the same global sums)
            if (world%rank == 0) write (output_unit, '(a,4es24.16)') &
                'terrace: runaway event search at s, f, df, d2f =', s, fdc
            if (self%evals > 100020) call stop_all('the event search did not converge (more than 1e5 ray '// &
                                                    'evaluations for one event): please report this input')
        end if
    end subroutine engine_ray_eval

    !> Global sums over owned atoms: sigma2 = sum |g_i|^2 |v_i|^2 / d (variance of dV/dt for
    !> isotropic velocities), a = mvv2e sum |g_i|^2/m_i, b = mvv2e sum g_i.v_i (g = -f).
    subroutine gradient_sums(eng, sigma2, a, b)
        type(engine_t), intent(inout) :: eng
        real(dp), intent(out) :: sigma2, a, b
        real(dp) :: acc(3), g2, m
        integer :: i
        acc = 0
        do i = 1, eng%atoms%nlocal
            m = eng%atoms%mass(eng%atoms%type(i))
            g2 = sum(eng%atoms%f(:, i)**2)
            acc(1) = acc(1) + g2*sum(eng%atoms%v(:, i)**2)
            acc(2) = acc(2) + g2/m
            acc(3) = acc(3) - sum(eng%atoms%f(:, i)*eng%atoms%v(:, i))
        end do
        call sum_all(acc)
        sigma2 = acc(1)/eng%box%dimension
        a = eng%cfg%units%mvv2e*acc(2)
        b = eng%cfg%units%mvv2e*acc(3)
    end subroutine gradient_sums

    !> The variance of dV/dt used to predict the level-crossing rate: that of the initial state,
    !> sum |g_i|^2 |v_i|^2 / d, or, when larger, the equilibrium estimate k_B T v.H.v / 4 from the
    !> curvature along the velocities (one ray pass). Equipartition gives <(g_i.v_i)^2> =
    !> k_B T tr(H_ii) k_B T / m_i = k_B T <v.H.v> per atom at temperature T; a crystal started on its
    !> lattice (g = 0) settles at about half its initial temperature, hence the 1/4. In an equilibrated
    !> state the first estimate is the larger one.
    real(dp) function crossing_sigma2(eng) result(sigma2)
        type(engine_t), intent(inout) :: eng
        real(dp) :: a, b, ray(4), kt
        call gradient_sums(eng, sigma2, a, b)
        call eng%ray_pass(0.0_dp, ray)
        kt = 0
        if (eng%dof() > 0) kt = 2*kinetic_energy(eng%atoms, eng%cfg%units)/eng%dof()
        sigma2 = max(sigma2, 0.25_dp*kt*ray(3))
    end function crossing_sigma2

    !> The terrace height: given, or chosen for a target mean event interval from the level-crossing
    !> rate, E|dV/dt| / h with E|dV/dt| = sqrt(2/pi) sigma (Rice), sigma^2 from crossing_sigma2.
    real(dp) function choose_terrace_height(eng) result(h)
        type(engine_t), intent(inout) :: eng
        real(dp) :: sigma2
        real(dp), parameter :: pi = 4*atan(1.0_dp)
        if (eng%cfg%terrace_height > 0) then
            h = eng%cfg%terrace_height
        else
            sigma2 = crossing_sigma2(eng)
            h = eng%cfg%target_mean_dt*sqrt(2/pi)*sqrt(sigma2)
            if (.not. (h > 0)) call stop_all(eng%cfg%where('integrator', 'target_mean_dt')// &
                ': cannot choose a terrace height: the initial state has no motion or no force')
        end if
    end function choose_terrace_height

    !> What to expect, from the initial state: mean event interval h / (sqrt(2/pi) sigma), the
    !> fraction of climbs that reflect, 1 - exp(-h a / (mvv2e^2 sigma^2)) (flux-weighted normal
    !> kinetic energy below h), and a stable velocity-Verlet step for the same scene, 0.005 tau with
    !> tau = sigma_LJ sqrt(m mvv2e / eps).
    subroutine print_es_estimates(eng, h)
        type(engine_t), intent(inout) :: eng
        real(dp), intent(in) :: h
        real(dp) :: sigma2, a, b, mean_dt, refl, tau, dt_vv, ray(4), omega2
        real(dp), parameter :: pi = 4*atan(1.0_dp)
        character(len=:), allocatable :: how
        call gradient_sums(eng, sigma2, a, b)
        sigma2 = crossing_sigma2(eng)
        tau = eng%pot%time_scale(eng%atoms%mass(1), eng%cfg%units%mvv2e)
        if (.not. (tau > 0)) then
            ! no natural time unit: 1/50 of the mean vibration period 2 pi / omega, omega^2 = v.H.v / v.M.v
            ! (a Rayleigh quotient over the thermal velocities; LJ's 0.005 tau is about the same fraction)
            call eng%ray_pass(0.0_dp, ray)
            omega2 = ray(3)/max(2*kinetic_energy(eng%atoms, eng%cfg%units), tiny(1.0_dp))
        end if
        if (world%rank /= 0) return
        mean_dt = huge(1.0_dp)
        if (sigma2 > 0) mean_dt = h/(sqrt(2/pi)*sqrt(sigma2))
        refl = 0
        if (sigma2 > 0) refl = 1 - exp(-h*a/(eng%cfg%units%mvv2e**2*sigma2))
        if (.not. (tau > 0)) then
            dt_vv = huge(1.0_dp)
            if (omega2 > 0) dt_vv = 2*pi/sqrt(omega2)/50
            how = ' (period/50)'
        else
            dt_vv = 0.005_dp*tau
            how = ' (0.005 tau)'
        end if
        write (output_unit, '(a,es12.5,1x,a)') '  terrace h  : ', h, trim(eng%cfg%units%energy)
        write (output_unit, '(a,es12.5,1x,a,a,f0.1,a)') '  expected   : mean event interval ~ ', mean_dt, &
            trim(eng%cfg%units%time), ', about ', 100*refl/2, ' % of events reflections'
        write (output_unit, '(a,es12.5,1x,a,a,f0.2,a)') '  vs Verlet  : a stable Verlet step here is ~ ', dt_vv, &
            trim(eng%cfg%units%time), how//'; ratio ', mean_dt/dt_vv, &
            ' (an event costs about 2-3 force passes: energy stepping pays off above ~3)'
    end subroutine print_es_estimates

    !> The event loop. Ends at t_end, or after max_events events.
    subroutine run_energy_stepping(eng, thermo, traj, h, t_end, max_events, sample_interval, sample_every, &
                                   traj_interval, traj_every, stats, ctl)
        type(engine_t), intent(inout), target :: eng
        type(thermo_writer_t), intent(inout) :: thermo
        type(trajectory_t), intent(inout) :: traj
        real(dp), intent(in) :: h, t_end, sample_interval, traj_interval
        integer(i8), intent(in) :: max_events, sample_every, traj_every
        type(es_stats_t), intent(out) :: stats
        type(run_control_t), intent(inout) :: ctl
        type(engine_ray_t) :: ray
        type(event_solver_t) :: solver
        type(crossing_t) :: res
        integer(i8) :: k, n_sample, last_events, last_evals, n_frame
        real(dp) :: t, lower, upper, p0(3), t_exp, t_next_sample, t_next_frame, window, sigma2, a, b, lam, vstar, trust, &
                    last_time, mvv2e
        logical :: have_c, sample_due, have_guess, ckpt_due, rebuilt, stop_now
        real(dp) :: c_guess, t_next_ckpt
        integer :: i, outcome
        real(dp) :: minv(size(eng%atoms%mass))
        type(energy_guard_t) :: guard
        type(thermostat_t) :: ts
        real(dp) :: t_coll
        logical :: collide
        integer :: changed

        ray%eng => eng
        mvv2e = eng%cfg%units%mvv2e
        do i = 1, size(minv)
            minv(i) = 1/eng%atoms%mass(i)
        end do
        t_next_ckpt = huge(1.0_dp)
        if (ctl%interval > 0) t_next_ckpt = (ctl%written + 1)*ctl%interval
        call ts%configure(eng%cfg, eng%natoms, merge(t_end, 0.0_dp, t_end < huge(1.0_dp)))
        t_coll = huge(1.0_dp)
        if (eng%restarted) then
            call restore_state()
        else
            call start_state()
        end if
        call schedule_collisions()
        do
            if (t >= t_end .or. stats%events >= max_events) exit
            window = max(0.0_dp, min(t_exp, t_next_sample, t_next_frame, t_next_ckpt, t_end, t_coll) - t)
            ray%evals = 0
            if (have_c .or. .not. have_guess) then
                call solver%first_crossing(ray, lower, upper, window, p0, have_c, trust, res)
            else
                call solver%first_crossing(ray, lower, upper, window, p0, have_c, trust, res, c_guess)
            end if
            stats%ray_evals = stats%ray_evals + ray%evals
            if (.not. res%found) then
                ! ---- window end: sample, list expiry or end of run; no kick
                ! (f, f', f'' and the virial at the window end, measured from the search origin: before
                ! the drift)
                p0 = res%fdc
                have_c = .true.
                if (ray%last_s /= window) call ray%eval(window, p0)
                call eng%drift(window)
                t = min(t_exp, t_next_sample, t_next_frame, t_next_ckpt, t_end, t_coll)
                ckpt_due = t >= t_next_ckpt
                ! Andersen collisions due now (before a list build reorders the atoms)
                collide = t >= t_coll
                if (collide) then
                    changed = ts%andersen_collide(eng%atoms, t)
                    if (ts%zero_momentum) call ts%remove_momentum(eng%atoms)
                end if
                ! well inside the nominal terrace again: edges shifted at earlier kicks revert
                if (p0(1) > k*h + solver%tol .and. p0(1) < (k + 1)*h - solver%tol) then
                    lower = k*h; upper = (k + 1)*h
                end if
                eng%pe = ray%last_out(1); eng%virial = ray%last_out(4)
                rebuilt = t >= t_exp .or. (ckpt_due .and. eng%plan%pair_mode == pair_cells)
                if (rebuilt) then
                    call eng%rebuild()
                    stats%rebuilds = stats%rebuilds + 1
                    t_exp = eng%list_expiry()
                    call min_all(t_exp)
                    t_exp = t + t_exp
                    if (ts%style == thermostat_andersen) call schedule_collisions()
                end if
                if (collide) then
                    ! new velocities: ghosts, list expiry, and V' and V'' at the search origin along them
                    if (.not. rebuilt) then
                        call eng%sync_ghosts()
                        t_exp = eng%list_expiry()
                        call min_all(t_exp)
                        t_exp = t + t_exp
                    end if
                    call ray%eval(0.0_dp, p0)
                    stats%ray_evals = stats%ray_evals + 1
                    have_c = .true.
                    t_coll = ts%andersen_first(eng%atoms)
                    call min_all(t_coll)
                end if
                if (t >= t_next_sample) then
                    call write_sample(t)
                    n_sample = n_sample + 1
                    t_next_sample = n_sample*sample_interval
                else if (t >= t_end) then
                    call write_sample(t)
                end if
                if (t >= t_next_frame) then
                    call write_frame(t)
                    n_frame = n_frame + 1
                    t_next_frame = n_frame*traj_interval
                end if
                ! a safe point: after a list build, or anywhere on the all-pairs path (its replicated
                ! atoms drift bitwise like their owners)
                ! (ecouple's per-rank parts are folded at every safe point: a restart sums them alike)
                if (ts%active() .and. (ckpt_due .or. rebuilt .or. eng%plan%pair_mode /= pair_cells)) call ts%fold()
                if (ctl%active .and. (ckpt_due .or. rebuilt .or. eng%plan%pair_mode /= pair_cells)) then
                    stop_now = ctl%stop_requested()
                    if (ckpt_due .or. stop_now) call checkpoint(ckpt_due)
                    if (ckpt_due) t_next_ckpt = (ctl%written + 1)*ctl%interval
                    if (stop_now) exit
                end if
                cycle
            end if
            ! ---- a level crossing at s = res%s: drift there, one force pass, the jump
            c_guess = res%c_near
            have_guess = .true.
            call eng%drift(res%s)
            t = t + res%s
            call eng%compute_forces(.true.)
            stats%force_passes = stats%force_passes + 1
            vstar = eng%pe
            call gradient_sums(eng, sigma2, a, b)
            call terrace_jump_lambda(a, b, h, res%level == level_upper, lam, outcome)
            if (outcome == jump_none .or. (res%level == level_upper .and. vstar < upper - solver%tol) .or. &
                (res%level == level_lower .and. vstar > lower + solver%tol)) then
                ! the predicted root fell short (or the state is already moving back): search on from here
                stats%verify_misses = stats%verify_misses + 1
                p0 = [vstar, b/mvv2e, 0.0_dp]
                have_c = .false.
                t_exp = eng%list_expiry(); call min_all(t_exp); t_exp = t + t_exp
                cycle
            end if
            select case (outcome)
            case (jump_climb)
                k = k + 1
                lower = vstar                 ! the state sits exactly on the new terrace's lower edge
                upper = (k + 1)*h
                stats%ups = stats%ups + 1
            case (jump_reflect)
                upper = vstar
                stats%reflections = stats%reflections + 1
            case (jump_fall)
                k = k - 1
                upper = vstar
                lower = k*h
                stats%downs = stats%downs + 1
            end select
            do i = 1, eng%atoms%nlocal
                eng%atoms%v(:, i) = eng%atoms%v(:, i) - lam*minv(eng%atoms%type(i))*eng%atoms%f(:, i)
            end do
            call eng%sync_ghosts()
            p0 = [vstar, (b + lam*a)/mvv2e, 0.0_dp]
            have_c = .false.
            stats%events = stats%events + 1
            trust = 4*t/stats%events
            t_exp = eng%list_expiry()
            call min_all(t_exp)
            t_exp = t + t_exp
            sample_due = sample_every > 0
            if (sample_due) sample_due = mod(stats%events, sample_every) == 0
            if (sample_due) call write_sample(t)
            if (traj_every > 0) then
                if (mod(stats%events, traj_every) == 0) call write_frame(t)
            end if
        end do
        stats%time = t
        if (ctl%stopped) return
        if (sample_every > 0 .and. mod(stats%events, max(sample_every, 1_i8)) /= 0) call write_sample(t)

    contains

        !> Next Andersen collision of every owned atom after t, and the global first one.
        subroutine schedule_collisions()
            if (ts%style /= thermostat_andersen) return
            call ts%andersen_schedule(eng%atoms, t)
            t_coll = ts%andersen_first(eng%atoms)
            call min_all(t_coll)
        end subroutine schedule_collisions

        subroutine start_state()
            ! the tolerance cannot be finer than the round-off of the total energy
            solver%tol = max(eng%cfg%root_tolerance*h, 64*epsilon(1.0_dp)*abs(eng%pe))
            if (world%rank == 0 .and. solver%tol > eng%cfg%root_tolerance*h) write (output_unit, '(a,es10.3,a)') &
                '  note       : root_tolerance raised to ', solver%tol/h, ' (round-off of the total energy)'
            t = 0
            k = floor(eng%pe/h, i8)
            lower = k*h
            upper = (k + 1)*h
            call gradient_sums(eng, sigma2, a, b)
            p0 = [eng%pe, b/mvv2e, 0.0_dp]
            have_c = .false.
            have_guess = .false.
            c_guess = 0
            n_sample = 1
            t_next_sample = huge(1.0_dp)
            if (sample_interval > 0) t_next_sample = sample_interval
            n_frame = 1
            t_next_frame = huge(1.0_dp)
            if (traj_interval > 0) t_next_frame = traj_interval
            t_exp = eng%list_expiry()
            call min_all(t_exp)
            trust = huge(1.0_dp)
            last_events = 0; last_evals = 0; last_time = 0
            call write_sample(0.0_dp)
            if (traj_interval > 0 .or. traj_every > 0) call write_frame(0.0_dp)
        end subroutine start_state

        !> The event loop's state as the interrupted run had it at its checkpoint.
        subroutine restore_state()
            logical :: ok
            ok = .true.
            associate (val => eng%restart_values)
                t = val%get_r('time', ok)
                k = val%get_i('es_k', ok)
                lower = val%get_r('es_lower', ok); upper = val%get_r('es_upper', ok)
                p0(1) = val%get_r('es_p0_f', ok); p0(2) = val%get_r('es_p0_df', ok); p0(3) = val%get_r('es_p0_d2f', ok)
                have_c = val%get_l('es_have_c', ok); have_guess = val%get_l('es_have_guess', ok)
                c_guess = val%get_r('es_c_guess', ok)
                trust = val%get_r('es_trust', ok)
                t_exp = val%get_r('es_t_exp', ok)
                n_sample = val%get_i('es_n_sample', ok); t_next_sample = val%get_r('es_t_next_sample', ok)
                n_frame = val%get_i('es_n_frame', ok); t_next_frame = val%get_r('es_t_next_frame', ok)
                last_events = val%get_i('es_last_events', ok); last_evals = val%get_i('es_last_evals', ok)
                last_time = val%get_r('es_last_time', ok)
                stats%events = val%get_i('es_events', ok); stats%reflections = val%get_i('es_reflections', ok)
                stats%ups = val%get_i('es_ups', ok); stats%downs = val%get_i('es_downs', ok)
                stats%ray_evals = val%get_i('es_ray_evals', ok); stats%force_passes = val%get_i('es_force_passes', ok)
                stats%verify_misses = val%get_i('es_verify_misses', ok); stats%rebuilds = val%get_i('es_rebuilds', ok)
                solver%tol = val%get_r('es_tol', ok)
                eng%pe = val%get_r('es_pe', ok); eng%virial = val%get_r('es_virial', ok)
                ray%last_s = val%get_r('es_ray_last_s', ok)
                ray%last_out(1) = val%get_r('es_ray_last_v', ok); ray%last_out(2) = val%get_r('es_ray_last_dv', ok)
                ray%last_out(3) = val%get_r('es_ray_last_d2v', ok); ray%last_out(4) = val%get_r('es_ray_last_w', ok)
            end associate
            if (ts%active()) call ts%restore(eng%restart_values, ok)
            call check_all(ok, trim(eng%cfg%read_checkpoint)//': &system: read_checkpoint: damaged checkpoint '// &
                           '(energy-stepping state missing)')
        end subroutine restore_state

        subroutine checkpoint(scheduled)
            logical, intent(in) :: scheduled
            type(ckpt_values_t) :: val
            logical :: ok
            character(len=512) :: msg
            call eng%timers%start(t_output)
            call val%put_r('h', h)
            if (ts%active()) call ts%save(val)
            call val%put_i('es_k', k)
            call val%put_r('es_lower', lower); call val%put_r('es_upper', upper)
            call val%put_r('es_p0_f', p0(1)); call val%put_r('es_p0_df', p0(2)); call val%put_r('es_p0_d2f', p0(3))
            call val%put_l('es_have_c', have_c); call val%put_l('es_have_guess', have_guess)
            call val%put_r('es_c_guess', c_guess)
            call val%put_r('es_trust', trust)
            call val%put_r('es_t_exp', t_exp)
            call val%put_i('es_n_sample', n_sample); call val%put_r('es_t_next_sample', t_next_sample)
            call val%put_i('es_n_frame', n_frame); call val%put_r('es_t_next_frame', t_next_frame)
            call val%put_i('es_last_events', last_events); call val%put_i('es_last_evals', last_evals)
            call val%put_r('es_last_time', last_time)
            call val%put_i('es_events', stats%events); call val%put_i('es_reflections', stats%reflections)
            call val%put_i('es_ups', stats%ups); call val%put_i('es_downs', stats%downs)
            call val%put_i('es_ray_evals', stats%ray_evals); call val%put_i('es_force_passes', stats%force_passes)
            call val%put_i('es_verify_misses', stats%verify_misses); call val%put_i('es_rebuilds', stats%rebuilds)
            call val%put_r('es_tol', solver%tol)
            call val%put_r('es_pe', eng%pe); call val%put_r('es_virial', eng%virial)
            call val%put_r('es_ray_last_s', ray%last_s)
            call val%put_r('es_ray_last_v', ray%last_out(1)); call val%put_r('es_ray_last_dv', ray%last_out(2))
            call val%put_r('es_ray_last_d2v', ray%last_out(3)); call val%put_r('es_ray_last_w', ray%last_out(4))
            ! the trajectory holds every frame the checkpoint counts, even if the run is killed next
            call traj%flush(ok, msg)
            call check_all(ok, 'trajectory: '//trim(msg))
            call ctl%write(eng, val, stats%events, t, thermo%lines, traj%frames(), scheduled)
            call eng%timers%stop(t_output)
        end subroutine checkpoint

        subroutine write_sample(time)
            real(dp), intent(in) :: time
            type(thermo_sample_t) :: s
            real(dp) :: extra(8), mean_dt, evals
            call eng%timers%start(t_output)
            s = eng%sample(stats%events, time)
            if (ts%active()) s%ecouple = ts%ecouple()
            call guard%check(s)
            mean_dt = 0; evals = 0
            if (stats%events > last_events) then
                mean_dt = (time - last_time)/(stats%events - last_events)
                evals = real(stats%ray_evals - last_evals, dp)/(stats%events - last_events)
            end if
            extra(1:6) = [real(stats%events, dp), real(stats%reflections, dp), mean_dt, evals, h, s%ke + k*h]
            if (ts%active()) then
                extra(7) = s%ecouple
                extra(8) = s%ke + k*h - extra(7)
                call thermo%write(s, extra)
            else
                call thermo%write(s, extra(1:6))
            end if
            last_events = stats%events; last_evals = stats%ray_evals; last_time = time
            call eng%timers%stop(t_output)
        end subroutine write_sample

        subroutine write_frame(time)
            real(dp), intent(in) :: time
            type(thermo_sample_t) :: s
            logical :: ok
            character(len=512) :: msg
            character(len=16), parameter :: names(4) = [character(len=16) :: 'events', 'reflections', &
                                                         'terrace_height', 'e_terraced']
            call eng%timers%start(t_output)
            s = eng%sample(stats%events, time)
            call traj%write(stats%events, time, eng%atoms, s, ok, msg, names, &
                            [real(stats%events, dp), real(stats%reflections, dp), h, s%ke + k*h])
            call check_all(ok, 'trajectory: '//trim(msg))
            call eng%timers%stop(t_output)
        end subroutine write_frame

    end subroutine run_energy_stepping

end module terrace_energy_stepping
