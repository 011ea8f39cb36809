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
!> (cell lists, or the sort and element remap of a mesh), and hold the whole event-loop state (terrace index, edges, the solver's last
!> values at the search origin, counters, next sample times), so a restart continues bitwise.
!>
!> With an Andersen thermostat (terrace_thermostat) each atom's next collision time (a Poisson
!> process of rate 1/damping, a function of seed, atom id and time only) is one more candidate of
!> the window minimum: at the earliest one the colliding atom gets a fresh Maxwell-Boltzmann
!> velocity, the terrace index and edges stay as they are (V is continuous), the ghosts' velocities
!> are re-synchronised and the search restarts from a ray pass at the collision point (V' and V''
!> along the new velocities); with zero_momentum the total momentum is removed after each collision.
!> With CSVR (stochastic velocity rescaling), or Andersen's global variant (&thermostat interval),
!> the thermostat acts at the multiples of its interval, one more candidate of the window minimum:
!> all velocities are scaled by Bussi's exact kinetic-energy propagator over the interval (one
!> global draw keyed by the rescaling's index), or all are resampled (keyed by atom id and index);
!> the terrace index and edges stay, and the search restarts from a ray pass as after a collision.
!> Thermo gains ecouple and econserve = K + k h - ecouple.
module terrace_energy_stepping
    use terrace_kinds, only: dp, i8, pi
    use terrace_text, only: fixed, sci_text
    use terrace_engine, only: engine_t
    use terrace_atoms, only: atoms_t
    use terrace_schedule, only: schedule_t
    use terrace_event_solver, only: ray_t, event_solver_t, crossing_t, level_upper, level_lower
    use terrace_observables, only: thermo_sample_t
    use terrace_calendar, only: calendar_t, cal_sample, cal_frame, cal_checkpoint, cal_list, cal_thermostat, cal_finish, &
                               cal_barostat
    use terrace_thermo, only: thermo_writer_t
    use terrace_timers, only: t_output, t_comm, t_search
    use terrace_mpi_env, only: world, sum_all, min_all
    use terrace_exact_sum, only: exact_sum_all
    use terrace_errors, only: stop_all, check_all
    use terrace_velocities, only: kinetic_energy
    use terrace_jump, only: terrace_jump_lambda, jump_climb, jump_reflect, jump_fall, jump_none
    use terrace_named_values, only: named_values_t
    use terrace_scene_plan, only: pair_all
    use, intrinsic :: iso_fortran_env, only: output_unit
    use terrace_run_parts, only: run_parts_t
    implicit none
    private

    !> 64 eps: the round-off bound, relative to an energy, below which the event search's tolerance is
    !> not set (round_off_floor, restore_state)
    real(dp), parameter :: round_off_eps = 64*epsilon(1.0_dp)

    !> The engine seen as a ray for the event solver: s is measured from the search origin,
    !> where the atoms are.
    type, extends(ray_t) :: engine_ray_t
        type(engine_t), pointer :: eng => null()
        real(dp) :: last_s = -huge(1.0_dp)
        real(dp) :: last_out(4) = 0
        !> progress lines during a long search (every 64 evaluations): the thermo writer, and
        !> the event count and time at the search's origin
        type(thermo_writer_t), pointer :: thermo => null()
        integer(i8) :: events = 0
        real(dp) :: t = 0
    contains
        procedure :: eval_ray => engine_ray_eval
    end type engine_ray_t

    type, public :: es_stats_t
        integer(i8) :: events = 0, reflections = 0, ups = 0, downs = 0
        integer(i8) :: ray_evals = 0, force_passes = 0, verify_misses = 0, rebuilds = 0
        real(dp) :: time = 0
        !> the conserved K + k h (less the thermostat's exchange) at the first and the last thermo
        !> sample of this run (of the continuation after a restart), for the closing summary
        real(dp) :: conserved_first = 0, conserved_last = 0
        logical :: have_conserved = .false.
    end type es_stats_t

    !> The event loop's whole state between two events: time, terrace index and edges, the solver's
    !> values at the search origin and its guesses, the next list expiry, sample and frame times,
    !> the counters. exchange() is the one place that writes it to a checkpoint and reads it back.
    type, public :: es_state_t
        real(dp) :: t = 0                          !< time reached
        integer(i8) :: k = 0                       !< terrace index: V_h = k h
        real(dp) :: lower = 0, upper = 0           !< the current terrace's edges (shifted after kicks)
        real(dp) :: p0(3) = 0                      !< (V, V', V'') at the search origin
        logical :: have_c = .false.                !< p0(3) is known
        logical :: have_guess = .false.            !< c_guess holds the last event's curvature
        real(dp) :: c_guess = 0, trust = huge(1.0_dp)
        !> the window ends: next sample and frame (by time: n * interval), checkpoint, the
        !> neighbour list's exact expiry (cal_list), thermostat event and end of the run
        type(calendar_t) :: cal
        !> the built list's own expiry (cal_list is also the pruned list's: a prune, not a build,
        !> before it); not in checkpoints: recomputed after the build a restart makes
        real(dp) :: t_exp_built = 0
        integer(i8) :: last_events = 0, last_evals = 0   !< at the last sample (means per sample)
        real(dp) :: last_time = 0
        type(es_stats_t) :: stats
        real(dp) :: tol = 0                        !< the solver's tolerance on V
        real(dp) :: pe = 0, virial = 0             !< the engine's V and W at the last evaluation
        real(dp) :: ray_last_s = -huge(1.0_dp), ray_last_out(4) = 0   !< the ray's memory
        !> windows ended by the calendar in a row without an event of the dynamics or a list expiry
        !> (the run-away guard, idle_limit; not in checkpoints: it only decides that guard)
        integer(i8) :: idle = 0
    contains
        procedure :: exchange => es_state_exchange
    end type es_state_t

    !> What energy stepping is made from (the run's units applied).
    type, public :: es_params_t
        real(dp) :: terrace_height = 0           !< h (0: chosen for target_mean_dt)
        real(dp) :: target_mean_dt = 0           !< the mean event interval h is chosen for
        real(dp) :: root_tolerance = 0           !< the event search's tolerance on V, in units of h
        !> for messages: the checkpoint a restart read, and where the deck sets the two keys above
        character(len=:), allocatable :: restart_from, where_height, where_mean_dt
    end type es_params_t

    !> One run of the event loop: what its procedures share.
    type, extends(run_parts_t) :: es_run_t
        type(engine_ray_t) :: ray
        type(event_solver_t) :: solver
        type(es_state_t) :: st
        type(es_stats_t) :: stats
        real(dp) :: h = 0, mvv2e = 1
        real(dp), allocatable :: minv(:)          !< 1/m of each type
        integer(i8) :: sample_every = 0, traj_every = 0   !< samples / frames every N events (0: by time)
    contains
        procedure :: exchange_own => es_exchange_own
    end type es_run_t

    character(len=*), parameter, public :: es_thermo_header = &
        ',events,reflections,mean_dt,evals_per_event,terrace_height,e_terraced'
    !> The observables a frame adds to the engine's (H5MD observables/NAME)
    character(len=16), parameter :: frame_names(4) = [character(len=16) :: 'events', 'reflections', &
                                                      'terrace_height', 'e_terraced']

    public :: run_energy_stepping, choose_terrace_height, print_es_estimates

contains

    subroutine engine_ray_eval(self, s, fdc)
        class(engine_ray_t), intent(inout) :: self
        real(dp), intent(in) :: s
        real(dp), intent(out) :: fdc(3)
        call self%eng%ray_pass(s, self%last_out)
        self%last_s = s
        fdc = self%last_out(1:3)
        if (iand(self%evals, 63) == 0 .and. associated(self%thermo)) call self%thermo%tick(self%events, self%t)
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
    !> with_energy: eng%pe and eng%virial are this rank's parts (compute_forces with partial) and
    !> are summed over ranks in the same reduction (where the potential does not sum them itself).
    subroutine gradient_sums(eng, sigma2, a, b, with_energy)
        type(engine_t), intent(inout) :: eng
        real(dp), intent(out) :: sigma2, a, b
        logical, intent(in), optional :: with_energy
        real(dp) :: acc(5), g2, m
        real(dp), allocatable, save :: part(:, :)   ! per-atom terms for the exact sums, kept between events
        integer :: i, n
        n = 3
        if (present(with_energy)) then
            if (with_energy) n = 5
        end if
        ! a potential that sums exactly (a mesh): these sums too, so that the kicks are the same
        ! bits on any number of ranks
        if (eng%pot%sums_global()) then
            if (allocated(part)) then
                if (size(part, 1) < eng%atoms%nlocal) deallocate (part)
            end if
            if (.not. allocated(part)) allocate (part(max(eng%atoms%nlocal + eng%atoms%nlocal/4, 1), 3))
            do i = 1, eng%atoms%nlocal
                if (eng%atoms%per_atom_mass) then
                    m = eng%atoms%rmass(i)
                else
                    m = eng%atoms%mass(eng%atoms%type(i))
                end if
                g2 = sum(eng%atoms%f(:, i)**2)
                part(i, :) = [g2*sum(eng%atoms%v(:, i)**2), g2/m, -sum(eng%atoms%f(:, i)*eng%atoms%v(:, i))]
            end do
            call exact_sum_all(part, eng%atoms%nlocal, eng%natoms, acc(1:3), .true.)
        else
            call plain_gradient_sums(eng%atoms, acc(1:3))
            acc(4:5) = [eng%pe, eng%virial]
            if (world%nprocs > 1) then
                call eng%timers%start(t_comm)
                call sum_all(acc(1:n))
                call eng%timers%stop(t_comm)
            end if
            if (n == 5) then
                eng%pe = acc(4); eng%virial = acc(5)
            end if
        end if
        sigma2 = acc(1)/eng%box%dimension
        a = eng%units%mvv2e*acc(2)
        b = eng%units%mvv2e*acc(3)
    end subroutine gradient_sums

    !> The velocity jump v_i = v_i - lam f_i / m_i of the n owned atoms, masses per atom (rmass) or
    !> by type (minv = 1/m of each type). One statement per component: written as v(:, i) = v(:, i)
    !> - c f(:, i), GCC made an inner loop of run-time extent 3 with a test per atom.
    pure subroutine kick_per_atom(n, lam, rmass, f, v)
        integer, intent(in) :: n
        real(dp), intent(in) :: lam, rmass(*), f(3, *)
        real(dp), intent(inout) :: v(3, *)
        integer :: i
        real(dp) :: c
        do i = 1, n
            c = lam/rmass(i)
            v(1, i) = v(1, i) - c*f(1, i); v(2, i) = v(2, i) - c*f(2, i); v(3, i) = v(3, i) - c*f(3, i)
        end do
    end subroutine kick_per_atom

    pure subroutine kick_by_type(n, lam, minv, type, f, v)
        integer, intent(in) :: n, type(*)
        real(dp), intent(in) :: lam, minv(*), f(3, *)
        real(dp), intent(inout) :: v(3, *)
        integer :: i
        real(dp) :: c
        do i = 1, n
            c = lam*minv(type(i))
            v(1, i) = v(1, i) - c*f(1, i); v(2, i) = v(2, i) - c*f(2, i); v(3, i) = v(3, i) - c*f(3, i)
        end do
    end subroutine kick_by_type

    !> This rank's (sum |g_i|^2 |v_i|^2, sum |g_i|^2/m_i, sum g_i.v_i), g = -f, over the owned atoms:
    !> eight interleaved partial sums (vectorised), added in a fixed order.
    pure subroutine plain_gradient_sums(atoms, acc)
        type(atoms_t), intent(in) :: atoms
        real(dp), intent(out) :: acc(3)
        if (atoms%per_atom_mass) then
            call gradient_terms(atoms%nlocal, atoms%f, atoms%v, atoms%rmass, [0], .true., acc)
        else
            call gradient_terms(atoms%nlocal, atoms%f, atoms%v, atoms%mass, atoms%type, .false., acc)
        end if
    end subroutine plain_gradient_sums

    !> plain_gradient_sums's arithmetic on the arrays themselves: m_i = mass(i) where per_atom, else
    !> mass(type(i)).
    pure subroutine gradient_terms(n, f, v, mass, type, per_atom, acc)
        integer, intent(in) :: n, type(*)
        real(dp), intent(in) :: f(3, *), v(3, *), mass(*)
        logical, intent(in) :: per_atom
        real(dp), intent(out) :: acc(3)
        real(dp) :: s1(8), s2(8), s3(8), m(8), g2
        integer :: i, l, nb
        s1 = 0; s2 = 0; s3 = 0
        nb = (n/8)*8
        do i = 1, nb, 8
            if (per_atom) then
                m = mass(i:i + 7)
            else
                m = mass(type(i:i + 7))
            end if
            do l = 1, 8
                g2 = f(1, i + l - 1)**2 + f(2, i + l - 1)**2 + f(3, i + l - 1)**2
                s1(l) = s1(l) + g2*(v(1, i + l - 1)**2 + v(2, i + l - 1)**2 + v(3, i + l - 1)**2)
                s2(l) = s2(l) + g2/m(l)
                s3(l) = s3(l) - (f(1, i + l - 1)*v(1, i + l - 1) + f(2, i + l - 1)*v(2, i + l - 1) + &
                                 f(3, i + l - 1)*v(3, i + l - 1))
            end do
        end do
        acc = [sum(s1), sum(s2), sum(s3)]
        do i = nb + 1, n
            if (per_atom) then
                m(1) = mass(i)
            else
                m(1) = mass(type(i))
            end if
            g2 = f(1, i)**2 + f(2, i)**2 + f(3, i)**2
            acc(1) = acc(1) + g2*(v(1, i)**2 + v(2, i)**2 + v(3, i)**2)
            acc(2) = acc(2) + g2/m(1)
            acc(3) = acc(3) - (f(1, i)*v(1, i) + f(2, i)*v(2, i) + f(3, i)*v(3, i))
        end do
    end subroutine gradient_terms

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
        call eng%timers%start(t_search)
        call eng%ray_pass(0.0_dp, ray)
        call eng%timers%stop(t_search)
        kt = 0
        if (eng%dof() > 0) kt = 2*kinetic_energy(eng%atoms, eng%units)/eng%dof()
        sigma2 = max(sigma2, 0.25_dp*kt*ray(3))
    end function crossing_sigma2

    !> The terrace height: given, or chosen for a target mean event interval from the level-crossing
    !> rate, E|dV/dt| / h with E|dV/dt| = sqrt(2/pi) sigma (Rice), sigma^2 from crossing_sigma2.
    real(dp) function choose_terrace_height(eng, p) result(h)
        type(engine_t), intent(inout) :: eng
        type(es_params_t), intent(in) :: p
        real(dp) :: sigma2
        if (p%terrace_height > 0) then
            h = p%terrace_height
        else
            sigma2 = crossing_sigma2(eng)
            h = p%target_mean_dt*sqrt(2/pi)*sqrt(sigma2)
            if (.not. (h > 0)) call stop_all(p%where_mean_dt// &
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
        character(len=:), allocatable :: how, words
        call gradient_sums(eng, sigma2, a, b)
        sigma2 = crossing_sigma2(eng)
        call eng%pot%time_unit(eng%atoms%mass(1), eng%units%mvv2e, tau, words)
        if (.not. (tau > 0)) then
            ! no natural time unit: 1/50 of the mean vibration period 2 pi / omega, omega^2 = v.H.v / v.M.v
            ! (a Rayleigh quotient over the thermal velocities; LJ's 0.005 tau is about the same fraction)
            call eng%timers%start(t_search)
            call eng%ray_pass(0.0_dp, ray)
            call eng%timers%stop(t_search)
            omega2 = ray(3)/max(2*kinetic_energy(eng%atoms, eng%units), tiny(1.0_dp))
        end if
        if (world%rank /= 0) return
        mean_dt = huge(1.0_dp)
        if (sigma2 > 0) mean_dt = h/(sqrt(2/pi)*sqrt(sigma2))
        refl = 0
        if (sigma2 > 0) refl = 1 - exp(-h*a/(eng%units%mvv2e**2*sigma2))
        if (.not. (tau > 0)) then
            dt_vv = huge(1.0_dp)
            if (omega2 > 0) dt_vv = 2*pi/sqrt(omega2)/50
            how = ' (period/50)'
        else
            dt_vv = 0.005_dp*tau
            how = ' ('//words//')'
        end if
        write (output_unit, '(a,es12.5,1x,a)') '  terrace h  : ', h, trim(eng%units%energy)
        if (mean_dt > 1.0e3_dp*dt_vv) then
            ! no forces and no curvature along the velocities (a body in rigid motion in its reference
            ! shape, a perfect crystal at rest): the level-crossing rate of the start says nothing
            write (output_unit, '(a)') '  expected   : not estimated (the start has almost no forces or curvature '// &
                'along its velocities, e.g. a rigid motion); the run log gives the measured mean interval'
            write (output_unit, '(a,es12.5,1x,a,a)') '  vs Verlet  : a stable Verlet step here is ~ ', dt_vv, &
                trim(eng%units%time), how
        else
            write (output_unit, '(a,es12.5,1x,a,a)') '  expected   : mean event interval ~ ', mean_dt, &
                trim(eng%units%time), ', about '//fixed(100*refl/2, 1)//' % of events reflections'
            write (output_unit, '(a,es12.5,1x,a,a)') '  vs Verlet  : a stable Verlet step here is ~ ', dt_vv, &
                trim(eng%units%time), how//'; ratio '//fixed(mean_dt/dt_vv, 2)// &
                ' (an event costs about 2-3 force passes: above ~3 energy stepping costs less per simulated '// &
                'time than Verlet at its stable step, though not at equal accuracy: doc/choosing_an_integrator.md)'
        end if
    end subroutine print_es_estimates

    !> The event loop. Ends at t_end, or after max_events events (sched), or at a stop request.
    subroutine run_energy_stepping(parts, p, h, sched, stats)
        type(run_parts_t), intent(in) :: parts
        type(es_params_t), intent(in) :: p
        real(dp), intent(in) :: h
        type(schedule_t), intent(in) :: sched
        type(es_stats_t), intent(out) :: stats
        type(es_run_t), target :: r
        type(crossing_t) :: res
        logical :: stop_now
        integer :: i
        r%run_parts_t = parts
        associate (eng => r%eng, ts => r%ts, out => r%out)
            r%ray%eng => r%eng
            r%ray%thermo => out%thermo
            r%h = h
            r%mvv2e = eng%units%mvv2e
            allocate (r%minv(size(eng%atoms%mass)))
            do i = 1, size(r%minv)
                r%minv(i) = 1/eng%atoms%mass(i)
            end do
            r%sample_every = sched%thermo_every
            r%traj_every = sched%traj_every
            if (eng%restarted) then
                call restore_state(r, p, sched)
            else
                call start_state(r, p, sched)
            end if
            call r%st%cal%on_grid(cal_checkpoint, out%ctl%interval, out%ctl%written + 1)
            r%st%cal%t(cal_finish) = sched%t_end
            call ts%schedule(eng%atoms, r%st%t)
            do
                if (r%st%t >= sched%t_end .or. r%stats%events >= sched%n_steps) exit
                r%st%cal%t(cal_thermostat) = ts%event_time()
                call search(r, res)
                if (res%found) then
                    call level_crossing(r, res)
                else
                    call window_end(r, res, stop_now)
                    if (stop_now) exit
                end if
            end do
            r%stats%time = r%st%t
            if (.not. out%ctl%stopped .and. r%sample_every > 0) then
                if (mod(r%stats%events, r%sample_every) /= 0) call write_sample(r, r%st%t)
            end if
            stats = r%stats
        end associate
    end subroutine run_energy_stepping

    !> The first level crossing in the window up to the calendar's next entry.
    subroutine search(r, res)
        type(es_run_t), intent(inout) :: r
        type(crossing_t), intent(out) :: res
        real(dp) :: window
        associate (st => r%st)
            window = max(0.0_dp, st%cal%next() - st%t)
            r%ray%evals = 0
            r%ray%events = r%stats%events; r%ray%t = st%t
            call r%eng%timers%start(t_search)
            if (st%have_c .or. .not. st%have_guess) then
                call r%solver%first_crossing(r%ray, st%lower, st%upper, window, st%p0, st%have_c, st%trust, res)
            else
                call r%solver%first_crossing(r%ray, st%lower, st%upper, window, st%p0, st%have_c, st%trust, res, &
                                             st%c_guess)
            end if
            call r%eng%timers%stop(t_search)
            r%stats%ray_evals = r%stats%ray_evals + r%ray%evals
        end associate
    end subroutine search

    !> No crossing in the window: drift to its end, the calendar entries due there (thermostat
    !> event, list prune or build, sample, frame), then at a safe point the stop poll and the
    !> checkpoint. stop_now: the run stops here (a checkpoint was written).
    subroutine window_end(r, res, stop_now)
        type(es_run_t), intent(inout) :: r
        type(crossing_t), intent(in) :: res
        logical, intent(out) :: stop_now
        logical :: ckpt_due, rebuilt, thermostat_event, safe, box_moved, grid_next
        real(dp) :: window
        associate (st => r%st, eng => r%eng, ts => r%ts, cal => r%st%cal, ctl => r%out%ctl)
            stop_now = .false.
            window = max(0.0_dp, cal%next() - st%t)
            ! (f, f', f'' and the virial at the window end, measured from the search origin: before
            ! the drift)
            st%p0 = res%fdc
            st%have_c = .true.
            if (r%ray%last_s /= window) then
                call eng%timers%start(t_search)
                call r%ray%eval(window, st%p0)
                call eng%timers%stop(t_search)
            end if
            call eng%drift(window)
            st%t = cal%next()
            ckpt_due = cal%due(cal_checkpoint, st%t)
            ! a thermostat event due now (Andersen collisions, a CSVR rescaling), before a list
            ! build reorders the atoms
            thermostat_event = cal%due(cal_thermostat, st%t)
            if (thermostat_event) call ts%apply_event(eng%atoms, st%t)
            ! well inside the nominal terrace again: edges shifted at earlier kicks revert
            if (st%p0(1) > st%k*r%h + r%solver%tol .and. st%p0(1) < (st%k + 1)*r%h - r%solver%tol) then
                st%lower = st%k*r%h; st%upper = (st%k + 1)*r%h
            end if
            eng%pe = r%ray%last_out(1); eng%virial = r%ray%last_out(4)
            ! a barostat event (a Monte Carlo volume move from the state at this time): an accepted
            ! move rebuilt the list; the terrace is that of the new V
            box_moved = .false.
            if (cal%due(cal_barostat, st%t)) then
                call r%bs%follow(eng%units%boltz*r%ts%target(st%t))     ! (a temperature ramp)
                call r%bs%apply_event(eng, cal%n(cal_barostat), box_moved)
                grid_next = cal%reached(cal_barostat, st%t)       ! on to the next grid point
                if (box_moved) then
                    st%k = floor(eng%pe/r%h, i8)
                    st%lower = st%k*r%h; st%upper = (st%k + 1)*r%h
                end if
            end if
            rebuilt = box_moved .or. st%t >= st%t_exp_built .or. (ckpt_due .and. eng%plan%pair_mode /= pair_all)
            if (.not. rebuilt .and. cal%due(cal_list, st%t)) then
                ! only the pruned list expired: prune it again (no build, no safe point)
                call eng%prune()
                if (.not. thermostat_event) call expiry_after(r, st%t)
            end if
            if (rebuilt) then
                if (.not. box_moved) call eng%rebuild()
                r%stats%rebuilds = r%stats%rebuilds + 1
                call expiry_after(r, st%t)
                call ts%schedule(eng%atoms, st%t)
            end if
            if (thermostat_event .or. box_moved) then
                ! new velocities or positions: ghosts, list expiry, and V, V' and V'' at the search
                ! origin
                if (.not. rebuilt) then
                    call eng%sync_ghosts()
                    call expiry_after(r, st%t)
                end if
                call eng%timers%start(t_search)
                call r%ray%eval(0.0_dp, st%p0)
                call eng%timers%stop(t_search)
                r%stats%ray_evals = r%stats%ray_evals + 1
                st%have_c = .true.
            end if
            if (cal%reached(cal_sample, st%t)) then
                call write_sample(r, st%t)
            else if (cal%due(cal_finish, st%t)) then
                call write_sample(r, st%t)     ! the end of the run is always sampled
            end if
            if (cal%reached(cal_frame, st%t)) call write_frame(r, st%t)
            call r%out%thermo%tick(r%stats%events, st%t)
            if ((rebuilt .and. .not. box_moved) .or. cal%due(cal_list, st%t)) then
                st%idle = 0
            else
                st%idle = st%idle + 1
                if (st%idle > idle_limit(eng%natoms, thermostat_event)) call run_away(r, thermostat_event, box_moved)
            end if
            ! a safe point: after a list build, or anywhere on the all-pairs path (its replicated
            ! atoms drift bitwise like their owners); without a pair list (a mesh) the build sorts
            ! the atoms and remaps the elements as a restart does, so only after one (ecouple's
            ! per-rank parts are folded at every safe point: a restart sums them alike)
            safe = ckpt_due .or. rebuilt .or. eng%plan%pair_mode == pair_all
            if (ts%active() .and. safe) call ts%fold()
            if (ctl%active .and. safe) then
                stop_now = ctl%stop_requested()
                if (ckpt_due .or. stop_now) call r%checkpoint(r%stats%events, r%st%t, ckpt_due)
                if (ckpt_due) call cal%on_grid(cal_checkpoint, ctl%interval, ctl%written + 1)
            end if
        end associate
    end subroutine window_end

    !> The most windows in a row the calendar may end with no event of the dynamics and no list
    !> expiry between them: 500, and for thermostat events 10 per atom if that is more (a dilute gas
    !> with Andersen collisions has many of them between list expiries). Beyond it an interval is
    !> far below the time the dynamics needs to move at all, and the run would never finish.
    pure integer(i8) function idle_limit(natoms, thermostat_event)
        integer(i8), intent(in) :: natoms
        logical, intent(in) :: thermostat_event
        idle_limit = 500
        if (thermostat_event) idle_limit = max(500_i8, 10*natoms)
    end function idle_limit

    !> The run-away guard's stop: the key whose schedule ended the last windows, with its interval.
    !> Every rank has the same calendar and events, so every rank stops here together.
    subroutine run_away(r, thermostat_event, box_moved)
        type(es_run_t), intent(in) :: r
        logical, intent(in) :: thermostat_event, box_moved
        character(len=:), allocatable :: key
        character(len=24) :: n
        real(dp) :: interval
        associate (cal => r%st%cal)
            if (thermostat_event) then
                key = '&thermostat interval (or damping: Andersen collisions)'
                interval = -1
            else if (box_moved .or. cal%interval(cal_barostat) > 0 .and. &
                     cal%n(cal_barostat) > 1 .and. cal%t(cal_barostat) - cal%interval(cal_barostat) >= r%st%t) then
                key = '&barostat interval'; interval = cal%interval(cal_barostat)
            else if (cal%interval(cal_frame) > 0 .and. cal%t(cal_frame) - cal%interval(cal_frame) >= r%st%t) then
                key = '&output trajectory_interval'; interval = cal%interval(cal_frame)
            else if (cal%interval(cal_sample) > 0) then
                key = '&output thermo_interval'; interval = cal%interval(cal_sample)
            else
                key = '&output checkpoint_interval'; interval = cal%interval(cal_checkpoint)
            end if
            if (interval > 0) key = key//' = '//sci_text(interval)//' '//r%out%thermo%time_unit
            write (n, '(i0)') idle_limit(r%eng%natoms, thermostat_event)
            call check_all(.false., 'energy stepping: '//trim(n)// &
                ' windows in a row ended by '//key//' with no event of the dynamics between them (time '// &
                sci_text(r%st%t)//' '//r%out%thermo%time_unit//'): the interval is far below the time the atoms need to move, and the run '// &
                'would not finish; give a longer one')
        end associate
    end subroutine run_away

    !> A level crossing at s = res%s: drift there, one force pass, the jump (climb, reflection or
    !> fall), the new terrace edges, the ghosts' velocities; samples and frames counted in events.
    subroutine level_crossing(r, res)
        type(es_run_t), intent(inout) :: r
        type(crossing_t), intent(in) :: res
        real(dp) :: sigma2, a, b, lam, vstar
        integer :: outcome
        associate (st => r%st, eng => r%eng, stats => r%stats, h => r%h, tol => r%solver%tol)
            st%c_guess = res%c_near
            st%have_guess = .true.
            st%idle = 0
            call eng%drift(res%s)
            st%t = st%t + res%s
            ! (V and the virial summed over ranks with the gradient sums: one reduction)
            call eng%compute_forces(.true., partial=.true.)
            stats%force_passes = stats%force_passes + 1
            call gradient_sums(eng, sigma2, a, b, with_energy=.true.)
            vstar = eng%pe
            call terrace_jump_lambda(a, b, h, res%level == level_upper, lam, outcome)
            if (outcome == jump_none .or. (res%level == level_upper .and. vstar < st%upper - tol) .or. &
                (res%level == level_lower .and. vstar > st%lower + tol)) then
                ! the predicted root fell short (or the state is already moving back): search on from here
                stats%verify_misses = stats%verify_misses + 1
                st%p0 = [vstar, b/r%mvv2e, 0.0_dp]
                st%have_c = .false.
                call expiry_after(r, st%t)
                return
            end if
            select case (outcome)
            case (jump_climb)
                st%k = st%k + 1
                st%lower = vstar                 ! the state sits exactly on the new terrace's lower edge
                st%upper = (st%k + 1)*h
                stats%ups = stats%ups + 1
            case (jump_reflect)
                st%upper = vstar
                stats%reflections = stats%reflections + 1
            case (jump_fall)
                st%k = st%k - 1
                st%upper = vstar
                st%lower = st%k*h
                stats%downs = stats%downs + 1
            end select
            if (eng%atoms%per_atom_mass) then
                call kick_per_atom(eng%atoms%nlocal, lam, eng%atoms%rmass, eng%atoms%f, eng%atoms%v)
            else
                call kick_by_type(eng%atoms%nlocal, lam, r%minv, eng%atoms%type, eng%atoms%f, eng%atoms%v)
            end if
            call eng%sync_ghosts()
            st%p0 = [vstar, (b + lam*a)/r%mvv2e, 0.0_dp]
            st%have_c = .false.
            stats%events = stats%events + 1
            st%trust = 4*st%t/stats%events
            call r%out%thermo%tick(stats%events, st%t)
            call expiry_after(r, st%t)
            if (r%sample_every > 0) then
                if (mod(stats%events, r%sample_every) == 0) call write_sample(r, st%t)
            end if
            if (r%traj_every > 0) then
                if (mod(stats%events, r%traj_every) == 0) call write_frame(r, st%t)
            end if
        end associate
    end subroutine level_crossing

    !> The neighbour list's expiry after time t0 (global minimum over ranks): the calendar's list
    !> entry (the pruned list's, when there is one) and the built list's own.
    subroutine expiry_after(r, t0)
        type(es_run_t), intent(inout) :: r
        real(dp), intent(in) :: t0
        real(dp) :: both(2)
        both(1) = r%eng%list_expiry(both(2))
        call min_all(both)
        r%st%cal%t(cal_list) = t0 + both(1)
        r%st%t_exp_built = t0 + both(2)
    end subroutine expiry_after

    !> A new run: the terrace of the initial V, the search origin, the calendar's first sample and
    !> frame, the list expiry; the first sample and frame written.
    subroutine start_state(r, p, sched)
        type(es_run_t), intent(inout) :: r
        type(es_params_t), intent(in) :: p
        type(schedule_t), intent(in) :: sched
        real(dp) :: sigma2, a, b
        associate (st => r%st, eng => r%eng, h => r%h)
            r%solver%tol = max(p%root_tolerance*h, round_off_floor(eng))
            if (world%rank == 0 .and. r%solver%tol > p%root_tolerance*h) write (output_unit, '(a,es10.3,a)') &
                '  note       : root_tolerance raised to ', r%solver%tol/h, ' (round-off of the total energy and its terms)'
            st%t = 0
            st%k = floor(eng%pe/h, i8)
            st%lower = st%k*h
            st%upper = (st%k + 1)*h
            call gradient_sums(eng, sigma2, a, b)
            st%p0 = [eng%pe, b/r%mvv2e, 0.0_dp]
            st%have_c = .false.
            st%have_guess = .false.
            st%c_guess = 0
            call st%cal%on_grid(cal_sample, sched%thermo_interval, 1_i8)
            call st%cal%on_grid(cal_frame, sched%traj_interval, 1_i8)
            call st%cal%on_grid(cal_barostat, r%bs%p%interval, 1_i8)
            call expiry_after(r, 0.0_dp)
            st%trust = huge(1.0_dp)
            st%last_events = 0; st%last_evals = 0; st%last_time = 0
            call write_sample(r, 0.0_dp)
            if (sched%traj_interval > 0 .or. sched%traj_every > 0) call write_frame(r, 0.0_dp)
        end associate
    end subroutine start_state

    !> The event loop's state as the interrupted run had it at its checkpoint.
    subroutine restore_state(r, p, sched)
        type(es_run_t), intent(inout) :: r
        type(es_params_t), intent(in) :: p
        type(schedule_t), intent(in) :: sched
        logical :: ok
        real(dp) :: t_list
        ok = .true.
        r%st%t = r%eng%restart_values%get_r('time', ok)
        ! the grids' spacings come from the deck (the checkpoint holds their next points)
        r%st%cal%interval(cal_sample) = sched%thermo_interval
        r%st%cal%interval(cal_frame) = sched%traj_interval
        r%st%cal%interval(cal_barostat) = r%bs%p%interval
        call r%exchange_own(r%eng%restart_values, .false., ok)
        ! the built list's expiry, as the run computed it after the build it checkpointed at (the
        ! list entry keeps the checkpoint's value)
        t_list = r%st%cal%t(cal_list)
        call expiry_after(r, r%st%t)
        r%st%cal%t(cal_list) = t_list
        call r%restore_coupling(r%eng%restart_values, ok)
        call check_all(ok, p%restart_from//': &system: read_checkpoint: damaged checkpoint '// &
                       '(energy-stepping state missing)')
        ! the checkpoint's tolerance, raised where it was written below the round-off of V's
        ! cancelling terms (which the run that wrote it now starts with: the same tolerance)
        r%solver%tol = max(r%solver%tol, round_off_eps*r%eng%pot%round_off_scale())
    end subroutine restore_state

    !> The finest tolerance V allows: the round-off of the total energy, and of its terms where they
    !> cancel (a potential's round_off_scale).
    real(dp) function round_off_floor(eng) result(tol)
        type(engine_t), intent(in) :: eng
        tol = round_off_eps*max(abs(eng%pe), eng%pot%round_off_scale())
    end function round_off_floor

    !> The event loop's own values of a checkpoint (run_parts_t's checkpoint adds the thermostat's
    !> and the barostat's), written (saving: with h, which the run's assembly reads back before the
    !> run) or read back into the solver, the engine's energy and the ray's last evaluation.
    subroutine es_exchange_own(self, values, saving, ok)
        class(es_run_t), intent(inout) :: self
        include 'checkpointed_args.inc'
        if (saving) then
            call values%put('h', self%h)
            self%st%tol = self%solver%tol
            self%st%pe = self%eng%pe; self%st%virial = self%eng%virial
            self%st%ray_last_s = self%ray%last_s; self%st%ray_last_out = self%ray%last_out
        end if
        call self%st%exchange(values, saving, self%stats, ok)
        if (saving) return
        self%solver%tol = self%st%tol
        self%eng%pe = self%st%pe; self%eng%virial = self%st%virial
        self%ray%last_s = self%st%ray_last_s; self%ray%last_out = self%st%ray_last_out
    end subroutine es_exchange_own

    !> A thermo sample: the engine's, then events, reflections, the mean event interval and ray
    !> evaluations per event since the last sample, h, and the conserved K + k h.
    subroutine write_sample(r, time)
        type(es_run_t), intent(inout) :: r
        real(dp), intent(in) :: time
        type(thermo_sample_t) :: s
        real(dp) :: mean_dt, evals
        associate (st => r%st, stats => r%stats)
            call r%eng%timers%start(t_output)
            s = r%eng%sample(stats%events, time)
            if (r%ts%active()) s%ecouple = r%ts%ecouple()
            mean_dt = 0; evals = 0
            if (stats%events > st%last_events) then
                mean_dt = (time - st%last_time)/(stats%events - st%last_events)
                evals = real(stats%ray_evals - st%last_evals, dp)/(stats%events - st%last_events)
            end if
            stats%conserved_last = s%ke + st%k*r%h
            if (r%ts%active()) stats%conserved_last = stats%conserved_last - s%ecouple
            if (.not. stats%have_conserved) stats%conserved_first = stats%conserved_last
            stats%have_conserved = .true.
            if (r%bs%active()) then        ! vol and the box lengths; P0 V in the conserved quantity
                call r%out%sample(s, s%ke + st%k*r%h + r%bs%pv(r%eng), [real(stats%events, dp), &
                                  real(stats%reflections, dp), mean_dt, evals, r%h, s%ke + st%k*r%h, &
                                  r%eng%box%volume(), r%eng%box%length])
            else
                call r%out%sample(s, s%ke + st%k*r%h, [real(stats%events, dp), real(stats%reflections, dp), mean_dt, &
                                                       evals, r%h, s%ke + st%k*r%h])
            end if
            st%last_events = stats%events; st%last_evals = stats%ray_evals; st%last_time = time
            call r%eng%timers%stop(t_output)
        end associate
    end subroutine write_sample

    !> A frame at time: the engine's sample, with the events, reflections, h and the conserved
    !> K + k h as its observables (frame_names).
    subroutine write_frame(r, time)
        type(es_run_t), intent(inout) :: r
        real(dp), intent(in) :: time
        associate (s => r%eng%sample(r%stats%events, time))
            call r%out%frame(r%eng, r%stats%events, time, s, frame_names, &
                             [real(r%stats%events, dp), real(r%stats%reflections, dp), r%h, s%ke + r%st%k*r%h])
        end associate
    end subroutine write_frame

    !> Write the state to (saving) or read it from a checkpoint's named values: every key once.
    !> (The time is the checkpoint's own 'time'; h and the thermostat's state are saved beside it.)
    subroutine es_state_exchange(self, val, saving, stats, ok)
        class(es_state_t), intent(inout) :: self
        type(named_values_t), intent(inout) :: val
        logical, intent(in) :: saving
        type(es_stats_t), intent(inout) :: stats
        logical, intent(inout) :: ok
        call x1('es_k', self%k)
        call x1('es_lower', self%lower); call x1('es_upper', self%upper)
        call x1('es_p0_f', self%p0(1)); call x1('es_p0_df', self%p0(2)); call x1('es_p0_d2f', self%p0(3))
        call x1('es_have_c', self%have_c); call x1('es_have_guess', self%have_guess)
        call x1('es_c_guess', self%c_guess)
        call x1('es_trust', self%trust)
        call x1('es_t_exp', self%cal%t(cal_list))
        call x1('es_n_sample', self%cal%n(cal_sample)); call x1('es_t_next_sample', self%cal%t(cal_sample))
        call x1('es_n_frame', self%cal%n(cal_frame)); call x1('es_t_next_frame', self%cal%t(cal_frame))
        call x1('es_last_events', self%last_events); call x1('es_last_evals', self%last_evals)
        call x1('es_last_time', self%last_time)
        call x1('es_events', stats%events); call x1('es_reflections', stats%reflections)
        call x1('es_ups', stats%ups); call x1('es_downs', stats%downs)
        call x1('es_ray_evals', stats%ray_evals); call x1('es_force_passes', stats%force_passes)
        call x1('es_verify_misses', stats%verify_misses); call x1('es_rebuilds', stats%rebuilds)
        call x1('es_tol', self%tol)
        call x1('es_pe', self%pe); call x1('es_virial', self%virial)
        call x1('es_ray_last_s', self%ray_last_s)
        call x1('es_ray_last_v', self%ray_last_out(1)); call x1('es_ray_last_dv', self%ray_last_out(2))
        call x1('es_ray_last_d2v', self%ray_last_out(3)); call x1('es_ray_last_w', self%ray_last_out(4))
        if (self%cal%interval(cal_barostat) > 0) then
            call x1('es_n_barostat', self%cal%n(cal_barostat)); call x1('es_t_next_barostat', self%cal%t(cal_barostat))
        end if
    contains
        !> One named value, real, integer(i8) or logical: written when saving, else read.
        subroutine x1(name, x)
            character(len=*), intent(in) :: name
            class(*), intent(inout) :: x
            call val%exchange(name, x, saving, ok)
        end subroutine x1
    end subroutine es_state_exchange


end module terrace_energy_stepping
