!> Event-driven molecular dynamics of stepped pair potentials (hard spheres, square wells).
!>
!> Atoms move in straight lines between events. Each atom keeps its position at its own time
!> (tl, a delayed state): an event brings only its atoms to the event time. The events:
!>  - pair events: a pair crosses one of its radii (terrace_stepped_pair: the time is a root of a
!>    quadratic in closed form; the crossing changes the two velocities along the line of centres,
!>    by -dU of normal kinetic energy, or reflects the pair when it cannot pay);
!>  - cell crossings: an atom leaves its cell of the grid (terrace_event_cells; cells of at least
!>    the largest radius, so that partners are found in the 27 neighbouring cells);
!>  - the run's calendar (terrace_calendar: thermo samples, trajectory frames, checkpoints, the
!>    end) as one more slot of the queue, at the calendar's next time.
!> The queue (terrace_event_queue) holds one slot per atom: the atom's earliest predicted event.
!> An event re-predicts only its atoms (over their neighbouring cells): O(neighbours + log N). A
!> slot whose partner has had an event since the prediction (per-atom event counters) is stale;
!> it is predicted again when it comes to the top (lazy invalidation).
!>
!> Pairs inside a well are remembered with their region (terrace_pair_map), so that a pair right
!> at a radius after crossing it is never taken for one outside it (round-off cannot make it cross
!> twice). Outputs are taken at exact times from the delayed states (x + v (t - tl)).
!>
!> Checkpoints: with &output checkpoint_file the thermo samples and the scheduled checkpoints are
!> safe points. At one, every atom is brought to its time and the whole event state is built again
!> from the atoms alone (build_state: numbering by cell, regions, energy, predictions), exactly as a
!> restart builds it from the checkpoint's atoms; the counters and the collision-virial sums of the
!> current sample interval go into the checkpoint's named values. A restart therefore runs the same
!> events with the same arithmetic as the uninterrupted run, on any rank count.
!>
!> Ranks: every rank holds all atoms and runs the same sequence of events (the same arithmetic in
!> the same order), so that every rank count gives the same results; rank 0 writes the thermo
!> CSV, and each rank writes its own atoms' rows of a trajectory frame.
module terrace_event_driven
    use, intrinsic :: iso_c_binding, only: c_double, c_int
    use terrace_kinds, only: dp, i8
    use terrace_text, only: int_text, real_text
    use terrace_engine, only: engine_t
    use terrace_calendar, only: calendar_t, cal_sample, cal_frame, cal_checkpoint, cal_finish, cal_thermostat
    use terrace_named_values, only: named_values_t
    use terrace_observables, only: thermo_sample_t
    use terrace_stepped_pair, only: stepped_table_t, inward_time, outward_time, collide, no_event
    use terrace_stepped_potential, only: stepped_table_of
    use terrace_event_queue, only: event_queue_t
    use terrace_event_cells, only: event_cells_t
    use terrace_pair_map, only: pair_map_t
    use terrace_velocities, only: atom_mass, hash_uniform
    use terrace_mpi_env, only: world, min_all, gather_counts
    use terrace_errors, only: stop_all, check_all
    use terrace_timers, only: t_pair, t_output
    use mpi_f08, only: MPI_Allgatherv, MPI_INTEGER, MPI_INTEGER8, MPI_DOUBLE_PRECISION
    use terrace_run_parts, only: run_parts_t
    implicit none
    private

    !> Extra thermo columns (after the common ones).
    character(len=*), parameter, public :: ed_thermo_header = ',events,collisions,collision_rate,bounces,'// &
                                                              'captures,escapes,captured_pairs'

    type, public :: ed_stats_t
        integer(i8) :: events = 0          !< all processed events (pair, cell, stale re-predictions)
        integer(i8) :: pair_events = 0     !< crossings of a radius (collisions, captures, escapes, bounces)
        integer(i8) :: cell_events = 0
        integer(i8) :: stale = 0           !< slots found stale at the top and predicted again
        integer(i8) :: core = 0            !< hard-core collisions
        integer(i8) :: bounces = 0         !< reflections at a finite step (a pair that could not escape / enter)
        integer(i8) :: captures = 0        !< inward crossings of a finite step
        integer(i8) :: escapes = 0         !< outward crossings of a finite step
        real(dp) :: time = 0
        real(dp) :: e_first = 0, e_last = 0, p_drift = 0
    end type ed_stats_t

    integer, parameter :: kind_cell = 0, kind_pair = 1

    !> What event-driven dynamics is made from (the run's units applied).
    type, public :: ed_params_t
        real(dp) :: t_end = 0                   !< the run ends at this time
        real(dp) :: sample_dt = 0, frame_dt = 0 !< thermo samples and trajectory frames (0: none)
        real(dp) :: temperature = -1            !< &system temperature (< 0: velocities as given)
        integer(i8) :: seed = 1
        logical :: reverse_velocities = .false.
        character(len=:), allocatable :: where_cells   !< where the deck sets the box (for messages)
        character(len=:), allocatable :: restart_from  !< the checkpoint a restart read (for messages)
    end type ed_params_t

    !> One run: the atoms (every atom on every rank, numbered in the order of their cells), their
    !> predicted events, the queue, the cells, the regions of the pairs inside a well, the running
    !> energies and the sums of the current sample interval.
    type, extends(run_parts_t) :: ed_run_t
        type(ed_params_t) :: p
        type(stepped_table_t) :: tab
        type(event_queue_t) :: q
        type(event_cells_t) :: cells
        type(pair_map_t) :: map
        type(calendar_t) :: cal
        type(ed_stats_t) :: stats
        integer :: n = 0, sched_slot = 0
        real(dp) :: length(3) = 0, inv_len(3) = 0
        real(dp), allocatable :: x(:, :), v(:, :), tl(:), m(:), ev_t(:)
        !> (8, atom) each atom's x, tl, v and type in one 64-byte column, kept equal to them (pack_atom
        !> after every change): the neighbour search reads one record per neighbour instead of four
        !> arrays, which at 10^6 atoms are four cache misses
        real(dp), allocatable :: pk(:, :)
        integer, allocatable :: typ(:), img(:, :), ev_kind(:), ev_partner(:), ev_code(:)
        integer, allocatable :: id_of(:), slot_of_id(:)      !< atom number (cell order) <-> id
        integer(i8), allocatable :: cnt(:), ev_pcount(:)
        real(dp) :: pe = 0, ke_run = 0                       !< running potential and kinetic energy
        !> sample interval sums: time integral of K up to t_ke, collision virial; its start, core count
        real(dp) :: ke_int = 0, t_ke = 0, virial = 0, t_last = 0
        integer(i8) :: core_last = 0
        !> thermostat: the energy it put in (summed over the atoms in id order: the same on every rank
        !> count), and buffers for the atoms a thermostat event changed (ids, new velocities)
        real(dp) :: ecouple = 0
        integer(i8), allocatable :: changed_id(:), mine_id(:)
        real(dp), allocatable :: changed_v(:, :), mine_v(:, :)
    contains
        procedure :: exchange_own => exchange
    end type ed_run_t

    public :: run_event_driven, check_event_driven_start

    interface
        !> A hint to load the cache line at x (prefetch.c).
        subroutine prefetch(x) bind(C, name='terrace_prefetch')
            import :: c_double
            real(c_double), intent(in) :: x
        end subroutine prefetch
        !> The candidates of cand(1:m) that may give atom i an event sooner than best, in order, into
        !> kept (room for m + 4); returns their count (event_filter.c).
        integer(c_int) function event_filter(pk, i, cand, m, t, xi, vi, length, inv_len, r2far, best, kept) &
            bind(C, name='terrace_event_filter')
            import :: c_double, c_int
            real(c_double), intent(in) :: pk(8, *), xi(3), vi(3), length(3), inv_len(3)
            integer(c_int), value :: i, m
            integer(c_int), intent(in) :: cand(*)
            real(c_double), value :: t, r2far, best
            integer(c_int), intent(out) :: kept(*)
        end function event_filter
    end interface

contains

    !> Before any output is opened: the box holds at least 3 cells of the largest radius along
    !> each direction, and no two hard cores overlap (over the engine's list: every pair within
    !> the cutoff + skin). Collective.
    subroutine check_event_driven_start(eng, p)
        type(engine_t), intent(inout) :: eng
        type(ed_params_t), intent(in) :: p
        type(stepped_table_t) :: tab
        logical :: found
        integer :: i, k, j
        real(dp) :: ratio, d, rsq
        call stepped_table_of(eng%pot, tab, found)
        call check_all(found, 'event_driven: the potential is not a stepped one')
        call check_all(all(eng%box%length >= 3*tab%rmax), p%where_cells// &
                       ': the box must be at least 3 interaction radii long in x, y and z for event-driven '// &
                       'integration (largest radius: '//real_text(tab%rmax)//')')
        ratio = huge(1.0_dp)
        if (allocated(eng%list%first)) then
            do i = 1, eng%atoms%nlocal
                do k = eng%list%first(i), eng%list%first(i + 1) - 1
                    j = eng%list%neigh(k)
                    d = tab%r(tab%nr(eng%atoms%type(i), eng%atoms%type(j)), eng%atoms%type(i), eng%atoms%type(j))
                    rsq = sum((eng%atoms%x(:, i) - eng%atoms%x(:, j))**2)
                    ratio = min(ratio, rsq/d**2)
                end do
            end do
        end if
        call min_all(ratio)
        call check_all(ratio >= 1, eng%source//': overlapping hard cores (closest pair at '//real_text(sqrt(ratio))// &
                       ' diameters)')
    end subroutine check_event_driven_start

    !> Run from t = 0 (a restart: the checkpoint's time) to p%t_end with thermo samples every
    !> p%sample_dt, frames every p%frame_dt (0: none), the run control's checkpoints and the
    !> thermostat's events (Andersen collisions at their exact times), all written through `out`.
    !> Collective (every rank runs the same events).
    subroutine run_event_driven(parts, p, stats)
        type(run_parts_t), intent(in) :: parts
        type(ed_params_t), intent(in) :: p
        type(ed_stats_t), intent(out) :: stats
        type(ed_run_t), target :: r
        logical :: found
        r%run_parts_t = parts; r%p = p
        associate (eng => r%eng, ts => r%ts)
            call stepped_table_of(eng%pot, r%tab, found)
            call check_all(found, 'event_driven: the potential is not a stepped one')
            r%length = eng%box%length
            r%inv_len = 1/r%length
            if (eng%restarted) then
                call restore_state(r)
            else
                call start_state(r)
            end if
            if (ts%active()) allocate (r%changed_id(r%n), r%changed_v(3, r%n), r%mine_id(r%n), r%mine_v(3, r%n))
            call event_loop(r)
            stats = r%stats
        end associate
    end subroutine run_event_driven

    !> A new run: the atoms (velocities drawn again with &system temperature), the calendar from
    !> t = 0, the first sample and frame.
    subroutine start_state(r)
        type(ed_run_t), intent(inout) :: r
        call build_state(r, 0.0_dp, r%p%temperature >= 0)
        r%ke_int = 0; r%t_ke = 0; r%virial = 0; r%t_last = 0; r%core_last = 0
        call grid(r, cal_sample, r%p%sample_dt, 1_i8)
        call grid(r, cal_frame, r%p%frame_dt, 1_i8)
        call grid(r, cal_checkpoint, r%out%ctl%interval, r%out%ctl%written + 1)
        r%cal%t(cal_finish) = r%p%t_end
        r%ecouple = 0
        call r%ts%schedule(r%eng%atoms, 0.0_dp)
        r%cal%t(cal_thermostat) = r%ts%event_time()
        call write_sample(r, 0.0_dp)
        r%stats%e_first = r%stats%e_last
        if (r%p%frame_dt > 0) call write_frame(r, 0.0_dp)
    end subroutine start_state

    !> A restart: the event state built from the checkpoint's atoms at its time, as the
    !> uninterrupted run built it there; counters, sums and calendar from its named values.
    subroutine restore_state(r)
        type(ed_run_t), intent(inout) :: r
        type(named_values_t) :: val
        real(dp) :: t
        logical :: ok
        ok = .true.
        val = r%eng%restart_values
        t = val%get_r('time', ok)
        call exchange(r, val, .false., ok)
        call check_all(ok, r%p%restart_from//': &system: read_checkpoint: damaged checkpoint '// &
                       '(event-driven state missing)')
        call build_state(r, t, .false.)
        r%t_ke = t
        r%cal%interval(cal_sample) = r%p%sample_dt          ! (the grids' spacings come from the deck)
        r%cal%interval(cal_frame) = r%p%frame_dt
        call grid(r, cal_checkpoint, r%out%ctl%interval, r%out%ctl%written + 1)
        r%cal%t(cal_finish) = r%p%t_end
        if (r%ts%active()) then
            call r%ts%restore(val, ok)
            call check_all(ok, r%p%restart_from//': &system: read_checkpoint: damaged checkpoint '// &
                           '(thermostat state missing)')
            call r%ts%schedule(r%eng%atoms, t)     ! (Andersen: the first collision of each atom after t)
        end if
        r%cal%t(cal_thermostat) = r%ts%event_time()
    end subroutine restore_state

    !> Calendar entry k on the multiples of interval from the n-th on (0: none), snapped.
    subroutine grid(r, k, interval, n)
        type(ed_run_t), intent(inout) :: r
        integer, intent(in) :: k
        real(dp), intent(in) :: interval
        integer(i8), intent(in) :: n
        call r%cal%on_grid(k, interval, n)
        call snap(r, k)
    end subroutine grid

    !> A grid time within 1e-9 intervals of the end is the end (no second sample a rounding error
    !> after the last one).
    subroutine snap(r, k)
        type(ed_run_t), intent(inout) :: r
        integer, intent(in) :: k
        if (r%cal%interval(k) <= 0) return
        if (abs(r%p%t_end - r%cal%t(k)) <= 1.0e-9_dp*r%cal%interval(k)) r%cal%t(k) = r%p%t_end
    end subroutine snap

    !> Grid entry k is due at t: it moves on to its next point (snapped).
    logical function reached(r, k, t)
        type(ed_run_t), intent(inout) :: r
        integer, intent(in) :: k
        real(dp), intent(in) :: t
        reached = r%cal%reached(k, t)
        if (reached) call snap(r, k)
    end function reached

    !> Events in time order until the end or an early stop; the final state into the engine.
    subroutine event_loop(r)
        type(ed_run_t), intent(inout) :: r
        integer :: slot, partner, code
        real(dp) :: t
        call r%q%set(r%sched_slot, r%cal%next())
        call r%eng%timers%start(t_pair)
        do
            slot = r%q%top()
            t = r%q%t(slot)
            if (slot == r%sched_slot) then
                call r%eng%timers%stop(t_pair)
                if (schedule(r, t)) exit
                call r%eng%timers%start(t_pair)
                cycle
            end if
            r%stats%events = r%stats%events + 1
            call r%out%thermo%tick(r%stats%events, t)
            if (r%ev_kind(slot) == kind_cell) then
                call cell_event(r, slot, t)
            else if (r%cnt(r%ev_partner(slot)) /= r%ev_pcount(slot)) then
                r%stats%stale = r%stats%stale + 1
                call predict(r, slot, t)
            else
                partner = r%ev_partner(slot); code = r%ev_code(slot)      ! (copies: predict rewrites the slot)
                call pair_event(r, slot, partner, code, t)
            end if
        end do
        r%stats%time = t
        if (.not. r%out%ctl%stopped) call put_state(r, t)
        r%eng%pe = r%pe
    end subroutine event_loop

    !> The calendar's slot at t: samples, frames, then at a safe point (a sample or a scheduled
    !> checkpoint, with a checkpoint file) the rebuild, the stop poll and the checkpoint. .true.:
    !> the run ends here (its end, or an early stop with a checkpoint). Then the slot's next time.
    logical function schedule(r, t) result(done)
        type(ed_run_t), intent(inout) :: r
        real(dp), intent(in) :: t
        logical :: sampled, ckpt_due, stop_now
        done = r%cal%due(cal_finish, t)
        if (.not. done .and. r%cal%due(cal_thermostat, t)) call thermostat_event(r, t)
        sampled = reached(r, cal_sample, t)
        if (sampled .or. done) call write_sample(r, t)
        if (reached(r, cal_frame, t)) call write_frame(r, t)
        if (.not. done .and. r%out%ctl%active) then
            ckpt_due = r%cal%due(cal_checkpoint, t)
            if (sampled .or. ckpt_due) then
                call rebuild_at(r, t)
                stop_now = r%out%ctl%stop_requested()
                if (ckpt_due .or. stop_now) call r%checkpoint(r%stats%events, t, ckpt_due)
                if (ckpt_due) call grid(r, cal_checkpoint, r%out%ctl%interval, r%out%ctl%written + 1)
                done = stop_now
            end if
        end if
        if (.not. done) call r%q%set(r%sched_slot, r%cal%next())
    end function schedule

    !> A safe point at t: the sums brought to t, every atom to t (into the engine's atoms), and
    !> the event state built again from them as a restart builds it.
    subroutine rebuild_at(r, t)
        type(ed_run_t), intent(inout) :: r
        real(dp), intent(in) :: t
        r%ke_int = r%ke_int + r%ke_run*(t - r%t_ke); r%t_ke = t
        call put_state(r, t)
        call build_state(r, t, .false.)
    end subroutine rebuild_at

    !> Write the run's counters, sums and calendar to (saving) or read them from a checkpoint's
    !> named values: every key once. (The time is the checkpoint's own 'time'.)
    subroutine exchange(self, values, saving, ok)
        class(ed_run_t), intent(inout) :: self
        include 'checkpointed_args.inc'
        call x1('ed_events', self%stats%events); call x1('ed_pair_events', self%stats%pair_events)
        call x1('ed_cell_events', self%stats%cell_events); call x1('ed_stale', self%stats%stale)
        call x1('ed_core', self%stats%core); call x1('ed_bounces', self%stats%bounces)
        call x1('ed_captures', self%stats%captures); call x1('ed_escapes', self%stats%escapes)
        call x1('ed_e_first', self%stats%e_first); call x1('ed_e_last', self%stats%e_last)
        call x1('ed_ke_int', self%ke_int); call x1('ed_virial', self%virial)
        call x1('ed_t_last', self%t_last); call x1('ed_core_last', self%core_last)
        call x1('ed_ecouple', self%ecouple)
        call x1('ed_n_sample', self%cal%n(cal_sample)); call x1('ed_t_next_sample', self%cal%t(cal_sample))
        call x1('ed_n_frame', self%cal%n(cal_frame)); call x1('ed_t_next_frame', self%cal%t(cal_frame))
    contains
        subroutine x1(name, x)
            character(len=*), intent(in) :: name
            class(*), intent(inout) :: x
            call values%exchange(name, x, saving, ok)
        end subroutine x1
    end subroutine exchange

    ! ------------------------------------------------------------------ the event state

    !> The event state at t from the engine's atoms alone: every atom on every rank in id order
    !> (velocities drawn again when draw), numbered by cell, the regions and energy of the pairs,
    !> the kinetic energy, and every atom's prediction. Collective (the gather).
    subroutine build_state(r, t, draw)
        type(ed_run_t), intent(inout) :: r
        real(dp), intent(in) :: t
        logical, intent(in) :: draw
        integer :: slot
        logical :: ok
        call gather_atoms(r, t)
        if (draw) call same_start_velocities(r)
        r%sched_slot = r%n + 1
        call r%cells%init(r%eng%box%lo, r%length, r%tab%rmax, r%n, ok)
        call check_all(ok, r%p%where_cells//': the box must be at least 3 interaction radii '// &
                       'long in x, y and z for event-driven integration (largest radius: '//real_text(r%tab%rmax)//')')
        call place_atoms(r)
        call find_regions(r)
        r%ke_run = kinetic(r)
        if (allocated(r%ev_t)) deallocate (r%ev_t, r%ev_kind, r%ev_partner, r%ev_code, r%ev_pcount, r%cnt)
        allocate (r%ev_t(r%n), r%ev_kind(r%n), r%ev_partner(r%n), r%ev_code(r%n), r%ev_pcount(r%n), r%cnt(r%n))
        r%cnt = 0; r%ev_kind = kind_cell; r%ev_partner = 0; r%ev_code = 0; r%ev_pcount = 0
        call r%q%init(r%n + 1)
        call r%eng%timers%start(t_pair)
        do slot = 1, r%n
            call predict(r, slot, t)
        end do
        call r%eng%timers%stop(t_pair)
    end subroutine build_state

    !> Every rank gets every atom, in id order (ids 1 .. natoms), at time t.
    subroutine gather_atoms(r, t)
        type(ed_run_t), intent(inout) :: r
        real(dp), intent(in) :: t
        integer, allocatable :: counts(:), displ(:), ti(:), ii(:, :)
        integer(i8), allocatable :: ids(:)
        real(dp), allocatable :: xx(:, :), vv(:, :), mm(:), mm_local(:)
        integer :: nl, k, n
        integer(i8) :: g
        associate (eng => r%eng)
            nl = eng%atoms%nlocal
            n = int(eng%natoms)
            r%n = n
            allocate (counts(world%nprocs), displ(world%nprocs))
            call gather_counts(nl, counts, displ)
            allocate (ids(n), ti(n), ii(3, n), xx(3, n), vv(3, n), mm(n))
            allocate (mm_local(nl))
            do k = 1, nl
                mm_local(k) = atom_mass(eng%atoms, k)
            end do
            call MPI_Allgatherv(eng%atoms%id, nl, MPI_INTEGER8, ids, counts, displ, MPI_INTEGER8, world%comm)
            call MPI_Allgatherv(eng%atoms%type, nl, MPI_INTEGER, ti, counts, displ, MPI_INTEGER, world%comm)
            call MPI_Allgatherv(mm_local, nl, MPI_DOUBLE_PRECISION, mm, counts, displ, MPI_DOUBLE_PRECISION, world%comm)
            call MPI_Allgatherv(eng%atoms%image, 3*nl, MPI_INTEGER, ii, 3*counts, 3*displ, MPI_INTEGER, world%comm)
            call MPI_Allgatherv(eng%atoms%x, 3*nl, MPI_DOUBLE_PRECISION, xx, 3*counts, 3*displ, MPI_DOUBLE_PRECISION, &
                                world%comm)
            call MPI_Allgatherv(eng%atoms%v, 3*nl, MPI_DOUBLE_PRECISION, vv, 3*counts, 3*displ, MPI_DOUBLE_PRECISION, &
                                world%comm)
            if (allocated(r%x)) deallocate (r%x, r%v, r%tl, r%m, r%typ, r%img)
            allocate (r%x(3, n), r%v(3, n), r%tl(n), r%m(n), r%typ(n), r%img(3, n))
            r%tl = t
            do k = 1, n
                g = ids(k)
                call check_all(g >= 1 .and. g <= n, eng%source//': event-driven integration needs atom ids 1 .. N')
                r%x(:, g) = xx(:, k); r%v(:, g) = vv(:, k); r%m(g) = mm(k); r%typ(g) = ti(k); r%img(:, g) = ii(:, k)
            end do
        end associate
    end subroutine gather_atoms

    !> &system temperature: the velocities drawn again as the scene builder draws them (the same
    !> normal deviates keyed by seed, id and component; drift removed; scaled to T with 3N - 3
    !> degrees of freedom; reversed with reverse_velocities), but with the sums taken over all
    !> atoms in id order on every rank: the scene builder's sums over ranks differ in their
    !> last bits between rank counts, which the dynamics' chaos would amplify.
    subroutine same_start_velocities(r)
        type(ed_run_t), intent(inout) :: r
        integer :: g, d, n
        real(dp) :: u1, u2, ptot(3), mtot, ke, t_now, temp
        real(dp), parameter :: two_pi = 8*atan(1.0_dp)
        associate (v => r%v, m => r%m, eng => r%eng)
            n = r%n
            temp = r%p%temperature
            do g = 1, n
                do d = 1, 3
                    u1 = hash_uniform(r%p%seed, int(g, i8), 2*d - 1)
                    u2 = hash_uniform(r%p%seed, int(g, i8), 2*d)
                    v(d, g) = sqrt(-2*log(u1))*cos(two_pi*u2)*sqrt(eng%units%boltz*temp/(m(g)*eng%units%mvv2e))
                end do
            end do
            ptot = 0; mtot = 0
            do g = 1, n
                ptot = ptot + m(g)*v(:, g)
                mtot = mtot + m(g)
            end do
            do g = 1, n
                v(:, g) = v(:, g) - ptot/mtot
            end do
            ke = 0
            do g = 1, n
                ke = ke + m(g)*(v(1, g)**2 + v(2, g)**2 + v(3, g)**2)
            end do
            ke = 0.5_dp*eng%units%mvv2e*ke
            if (n > 1 .and. ke > 0) then
                t_now = 2*ke/((3*real(n, dp) - 3)*eng%units%boltz)
                v = v*sqrt(temp/t_now)
            end if
            if (r%p%reverse_velocities) v = -v
        end associate
    end subroutine same_start_velocities

    !> Wrap the positions into the box, number the atoms in the order of their cells (atoms
    !> that meet sit close in memory; slot_of_id and id_of map between ids and these numbers)
    !> and put every atom into its cell.
    subroutine place_atoms(r)
        type(ed_run_t), intent(inout) :: r
        integer :: i, d, k, c(3), n
        integer, allocatable :: cell_of(:), start(:), perm(:), ic(:, :)
        real(dp) :: s
        n = r%n
        if (allocated(r%id_of)) deallocate (r%id_of, r%slot_of_id)
        allocate (cell_of(n), ic(3, n), start(product(r%cells%nc) + 1), perm(n), r%id_of(n), r%slot_of_id(n))
        do i = 1, n
            do d = 1, 3
                s = floor((r%x(d, i) - r%eng%box%lo(d))*r%inv_len(d))
                r%x(d, i) = r%x(d, i) - s*r%length(d)
                r%img(d, i) = r%img(d, i) + int(s)
                c(d) = int((r%x(d, i) - r%eng%box%lo(d))/r%cells%w(d))
                c(d) = min(max(c(d), 0), r%cells%nc(d) - 1)
            end do
            ic(:, i) = c
            cell_of(i) = r%cells%index(c)
        end do
        start = 0                                   ! counting sort by cell (stable: by id within a cell)
        do i = 1, n
            start(cell_of(i) + 1) = start(cell_of(i) + 1) + 1
        end do
        start(1) = 1
        do k = 2, size(start)
            start(k) = start(k) + start(k - 1)
        end do
        do i = 1, n
            perm(start(cell_of(i))) = i
            start(cell_of(i)) = start(cell_of(i)) + 1
        end do
        r%x = r%x(:, perm); r%v = r%v(:, perm); r%m = r%m(perm); r%typ = r%typ(perm); r%img = r%img(:, perm)
        ic = ic(:, perm)
        do k = 1, n
            r%id_of(k) = perm(k)
            r%slot_of_id(perm(k)) = k
        end do
        do i = n, 1, -1          ! (inserted last to first: each cell's list runs in id order)
            call r%cells%insert(i, ic(:, i))
        end do
        if (allocated(r%pk)) deallocate (r%pk)
        allocate (r%pk(8, n))
        do i = 1, n
            call pack_atom(r, i)
        end do
    end subroutine place_atoms

    !> Atom i's column of pk from x, tl, v and its type.
    pure subroutine pack_atom(r, i)
        type(ed_run_t), intent(inout) :: r
        integer, intent(in) :: i
        r%pk(1:3, i) = r%x(:, i); r%pk(4, i) = r%tl(i); r%pk(5:7, i) = r%v(:, i); r%pk(8, i) = real(r%typ(i), dp)
    end subroutine pack_atom

    !> Regions of the pairs inside a radius (overlaps of hard cores are refused), and the
    !> potential energy.
    subroutine find_regions(r)
        type(ed_run_t), intent(inout) :: r
        integer :: i, j, s, c, nb(27)
        real(dp) :: dx(3)
        r%pe = 0
        if (r%tab%has_steps) call r%map%init(int(r%n, i8), int(r%n, i8)*4)
        do i = 1, r%n
            call neighbour_cells(r%cells, i, nb)
            do c = 1, 27
                j = r%cells%head(nb(c))
                do while (j > 0)
                    if (j > i) then
                        dx = r%x(:, i) - r%x(:, j)
                        dx = dx - r%length*anint(dx*r%inv_len)
                        s = r%tab%region_of(r%typ(i), r%typ(j), sum(dx**2))
                        if (s == r%tab%nr(r%typ(i), r%typ(j))) call stop_all(r%eng%source//': overlapping hard '// &
                            'cores (atoms '//int_text(r%id_of(i))//' and '//int_text(r%id_of(j))//' closer than their '// &
                            'diameter)')
                        if (s > 0) then
                            call r%map%put(i, j, s)
                            r%pe = r%pe + r%tab%u(s, r%typ(i), r%typ(j))
                        end if
                    end if
                    j = r%cells%nxt(j)
                end do
            end do
        end do
    end subroutine find_regions

    !> The 27 cells around atom i's cell (periodic).
    pure subroutine neighbour_cells(cells, i, nb)
        type(event_cells_t), intent(in) :: cells
        integer, intent(in) :: i
        integer, intent(out) :: nb(27)
        integer :: a, b, c, k, cc(3)
        k = 0
        do c = -1, 1
            do b = -1, 1
                do a = -1, 1
                    cc = cells%ic(:, i) + [a, b, c]
                    cc = modulo(cc, cells%nc)
                    k = k + 1
                    nb(k) = 1 + cc(1) + cells%nc(1)*(cc(2) + cells%nc(2)*cc(3))
                end do
            end do
        end do
    end subroutine neighbour_cells

    ! ------------------------------------------------------------------ events

    !> Atom i's earliest event after t (its cell crossing or a crossing of a radius with an atom
    !> of the 27 cells around it) into its slot.
    subroutine predict(r, i, t)
        type(ed_run_t), intent(inout) :: r
        integer, intent(in) :: i
        real(dp), intent(in) :: t
        real(dp) :: best
        integer :: best_j, best_code
        call earliest_event(r%pk, r%tab, r%cells, r%map, r%length, r%inv_len, i, t, best, best_j, best_code)
        r%ev_code(i) = best_code; r%ev_partner(i) = best_j
        if (best_j > 0) then
            r%ev_kind(i) = kind_pair; r%ev_pcount(i) = r%cnt(best_j)
        else
            r%ev_kind(i) = kind_cell
        end if
        r%ev_t(i) = t + best
        call r%q%set(i, r%ev_t(i))
    end subroutine predict

    !> The search of predict on plain arrays (the hot loop: no derived-type indirection inside it):
    !> the time from t to atom i's earliest event, its partner (0: a cell crossing) and its code
    !> (the radius crossed, > 0 inward, < 0 outward; a cell crossing: the face).
    subroutine earliest_event(pk, tab, cells, map, length, inv_len, i, t, best, best_j, best_code)
        real(dp), intent(in), contiguous :: pk(:, :)
        real(dp), intent(in) :: length(3), inv_len(3), t
        integer, intent(in) :: i
        type(stepped_table_t), intent(in) :: tab
        type(event_cells_t), intent(in) :: cells
        type(pair_map_t), intent(in) :: map
        real(dp), intent(out) :: best
        integer, intent(out) :: best_j, best_code
        integer, parameter :: chunk = 128
        real(dp) :: xi(3), dx(3), dv(3), dt, b, rsq, r2far
        integer :: nb(27), c, j, jn, k, m, dir, s, ti, tj, nr, cand(chunk + 4), kept(chunk + 4), nk
        xi = pk(1:3, i) + pk(5:7, i)*(t - pk(4, i))
        call cells%crossing(i, xi, pk(5:7, i), best, dir)
        best_j = 0; best_code = dir
        call neighbour_cells(cells, i, nb)
        ti = int(pk(8, i))
        r2far = 0
        do tj = 1, tab%ntypes
            r2far = max(r2far, tab%r2(1, ti, tj))
        end do
        ! The atoms of the 27 cells are listed first (list heads and links: loads that do not wait
        ! on the pair arithmetic), up to chunk at a time, each listed atom's record prefetched, then
        ! filtered (event_filter.c: those that provably cannot come before best, the cell
        ! crossing, dropped, most of them in a liquid) and the rest searched in the same order:
        ! the records' cache misses (one per neighbour at 10^6 atoms) overlap instead of each
        ! waiting on the search of the one before.
        c = 0; jn = 0                    ! (jn: the next atom to list)
        do
            m = 0
            do while (m < chunk)
                do while (jn == 0 .and. c < 27)
                    c = c + 1
                    jn = cells%head(nb(c))
                end do
                if (jn == 0) exit
                m = m + 1
                cand(m) = jn
                call prefetch(pk(1, jn))
                jn = cells%nxt(jn)
            end do
            nk = event_filter(pk, i, cand, m, t, xi, pk(5:7, i), length, inv_len, r2far, best, kept)
            do k = 1, nk
                j = kept(k)
                if (j == i) cycle
                dx = xi - (pk(1:3, j) + pk(5:7, j)*(t - pk(4, j)))
                dx = dx - length*nearest_image(dx*inv_len)
                dv = pk(5:7, i) - pk(5:7, j)
                tj = int(pk(8, j))
                rsq = dx(1)**2 + dx(2)**2 + dx(3)**2
                s = 0
                if (tab%has_steps) then
                    if (rsq <= tab%r2(1, ti, tj)*(1 + 1.0e-8_dp)) s = map%get(i, j)
                end if
                if (s == 0) then
                    b = dx(1)*dv(1) + dx(2)*dv(2) + dx(3)*dv(3)
                    if (b < 0) then
                        dt = inward_time(dx, dv, tab%r2(1, ti, tj))
                        if (dt < best) then
                            best = dt; best_j = j; best_code = 1
                        end if
                    end if
                else
                    nr = tab%nr(ti, tj)
                    if (s < nr) then
                        dt = inward_time(dx, dv, tab%r2(s + 1, ti, tj))
                        if (dt < best) then
                            best = dt; best_j = j; best_code = s + 1
                        end if
                    end if
                    dt = outward_time(dx, dv, tab%r2(s, ti, tj))
                    if (dt < best) then
                        best = dt; best_j = j; best_code = -s
                    end if
                end if
            end do
            if (jn == 0 .and. c == 27) exit
        end do
    end subroutine earliest_event

    !> anint(y) for |y| < 1.5 (a separation over the box length between atoms of neighbouring
    !> cells), without a call of the library's round: the same value, so the same bits.
    elemental real(dp) function nearest_image(y) result(k)
        real(dp), intent(in) :: y
        k = 0
        if (y >= 0.5_dp) then
            k = 1
        else if (y <= -0.5_dp) then
            k = -1
        end if
    end function nearest_image

    !> The pair (i, j) crosses radius |code| at t, inward (code > 0) or outward (code < 0).
    subroutine pair_event(r, i, j, code, t)
        type(ed_run_t), intent(inout) :: r
        integer, intent(in) :: i, j, code
        real(dp), intent(in) :: t
        real(dp) :: dx(3), du, w, ke_old
        integer :: k, nr, s_new, ti, tj
        logical :: crossed
        associate (x => r%x, v => r%v, tl => r%tl, m => r%m, tab => r%tab, stats => r%stats)
            x(:, i) = x(:, i) + v(:, i)*(t - tl(i)); tl(i) = t
            x(:, j) = x(:, j) + v(:, j)*(t - tl(j)); tl(j) = t
            dx = x(:, i) - x(:, j)
            dx = dx - r%length*anint(dx*r%inv_len)
            ti = r%typ(i); tj = r%typ(j)
            nr = tab%nr(ti, tj)
            k = abs(code)
            if (code > 0) then
                s_new = k
                du = huge(1.0_dp)
                if (k < nr) du = tab%u(k, ti, tj) - tab%u(k - 1, ti, tj)
            else
                s_new = k - 1
                du = tab%u(k - 1, ti, tj) - tab%u(k, ti, tj)
            end if
            ke_old = 0.5_dp*(m(i)*sum(v(:, i)**2) + m(j)*sum(v(:, j)**2))
            call collide(dx, v(:, i), v(:, j), m(i), m(j), du/r%eng%units%mvv2e, crossed, w)
            r%ke_int = r%ke_int + r%ke_run*(t - r%t_ke); r%t_ke = t
            r%ke_run = r%ke_run + (0.5_dp*(m(i)*sum(v(:, i)**2) + m(j)*sum(v(:, j)**2)) - ke_old)
            r%virial = r%virial + w
            stats%pair_events = stats%pair_events + 1
            if (crossed) then
                r%pe = r%pe + du
                call r%map%put(i, j, s_new)
                if (code > 0) then
                    stats%captures = stats%captures + 1
                else
                    stats%escapes = stats%escapes + 1
                end if
            else if (code > 0 .and. k == nr) then
                stats%core = stats%core + 1
            else
                stats%bounces = stats%bounces + 1
            end if
        end associate
        r%cnt(i) = r%cnt(i) + 1; r%cnt(j) = r%cnt(j) + 1
        call pack_atom(r, i); call pack_atom(r, j)
        call predict(r, i, t)
        call predict(r, j, t)
    end subroutine pair_event

    !> Atom i leaves its cell through face ev_code(i) at t (across the box: wrapped, image counted).
    subroutine cell_event(r, i, t)
        type(ed_run_t), intent(inout) :: r
        integer, intent(in) :: i
        real(dp), intent(in) :: t
        integer :: d, c(3)
        r%stats%cell_events = r%stats%cell_events + 1
        r%x(:, i) = r%x(:, i) + r%v(:, i)*(t - r%tl(i)); r%tl(i) = t
        d = abs(r%ev_code(i))
        c = r%cells%ic(:, i)
        c(d) = c(d) + sign(1, r%ev_code(i))
        if (c(d) >= r%cells%nc(d)) then
            c(d) = 0; r%x(d, i) = r%x(d, i) - r%length(d); r%img(d, i) = r%img(d, i) + 1
        else if (c(d) < 0) then
            c(d) = r%cells%nc(d) - 1; r%x(d, i) = r%x(d, i) + r%length(d); r%img(d, i) = r%img(d, i) - 1
        end if
        call r%cells%remove(i)
        call r%cells%insert(i, c)
        call pack_atom(r, i)
        call predict(r, i, t)
    end subroutine cell_event

    !> The thermostat's event at t (Andersen: the atoms whose collision time it is get new
    !> velocities): the hook acts on this rank's atoms in the engine; the atoms it changed are
    !> gathered and, in id order on every rank, brought to t, given their new velocities and
    !> predicted again (their partners' predictions go stale by the event counters).
    subroutine thermostat_event(r, t)
        type(ed_run_t), intent(inout) :: r
        real(dp), intent(in) :: t
        integer :: k, g, nl, nc, i
        integer :: counts(world%nprocs), displ(world%nprocs)
        integer(i8) :: id
        real(dp) :: vnew(3), de
        associate (atoms => r%eng%atoms)
            nl = atoms%nlocal
            do k = 1, nl
                atoms%v(:, k) = r%v(:, r%slot_of_id(int(atoms%id(k))))
            end do
            call r%ts%apply_event(atoms, t)
            nc = 0
            do k = 1, nl
                g = r%slot_of_id(int(atoms%id(k)))
                if (any(atoms%v(:, k) /= r%v(:, g))) then
                    nc = nc + 1
                    r%mine_id(nc) = atoms%id(k); r%mine_v(:, nc) = atoms%v(:, k)
                end if
            end do
            call gather_counts(nc, counts, displ)
            call MPI_Allgatherv(r%mine_id, nc, MPI_INTEGER8, r%changed_id, counts, displ, MPI_INTEGER8, &
                                world%comm)
            call MPI_Allgatherv(r%mine_v, 3*nc, MPI_DOUBLE_PRECISION, r%changed_v, 3*counts, 3*displ, &
                                MPI_DOUBLE_PRECISION, world%comm)
        end associate
        nc = sum(counts)
        call sort_changed(r%changed_id(1:nc), r%changed_v(:, 1:nc))
        r%ke_int = r%ke_int + r%ke_run*(t - r%t_ke); r%t_ke = t
        do k = 1, nc
            id = r%changed_id(k); vnew = r%changed_v(:, k)
            i = r%slot_of_id(int(id))
            r%x(:, i) = r%x(:, i) + r%v(:, i)*(t - r%tl(i)); r%tl(i) = t
            de = 0.5_dp*r%m(i)*(sum(vnew**2) - sum(r%v(:, i)**2))
            r%ke_run = r%ke_run + de
            r%ecouple = r%ecouple + de*r%eng%units%mvv2e
            r%v(:, i) = vnew
            r%cnt(i) = r%cnt(i) + 1
            call pack_atom(r, i)
        end do
        call r%eng%timers%start(t_pair)
        do k = 1, nc
            call predict(r, r%slot_of_id(int(r%changed_id(k))), t)
        end do
        call r%eng%timers%stop(t_pair)
        r%cal%t(cal_thermostat) = r%ts%event_time()
    end subroutine thermostat_event

    !> The changed atoms in id order (insertion sort: a thermostat event changes few).
    pure subroutine sort_changed(id, v)
        integer(i8), intent(inout) :: id(:)
        real(dp), intent(inout) :: v(:, :)
        integer :: a, b
        integer(i8) :: key
        real(dp) :: vk(3)
        do a = 2, size(id)
            key = id(a); vk = v(:, a)
            b = a - 1
            do while (b >= 1)
                if (id(b) <= key) exit
                id(b + 1) = id(b); v(:, b + 1) = v(:, b)
                b = b - 1
            end do
            id(b + 1) = key; v(:, b + 1) = vk
        end do
    end subroutine sort_changed

    ! ------------------------------------------------------------------ outputs

    !> A thermo line at t: the sample, the pressure from the kinetic energy's time integral and the
    !> collision virial over the interval since the last line, the event counters.
    subroutine write_sample(r, t)
        type(ed_run_t), intent(inout) :: r
        real(dp), intent(in) :: t
        type(thermo_sample_t) :: s
        real(dp) :: tau, rate
        associate (eng => r%eng, stats => r%stats)
            call eng%timers%start(t_output)
            s = sample(r, t)
            tau = t - r%t_last
            r%ke_int = r%ke_int + r%ke_run*(t - r%t_ke); r%t_ke = t
            if (tau > 0) then
                s%press = (2*r%ke_int + r%virial)/tau*eng%units%mvv2e/(3*eng%box%volume())*eng%units%nktv2p
                rate = 2*real(stats%core - r%core_last, dp)/(r%n*tau)
            else
                s%press = 2*s%ke/(3*eng%box%volume())*eng%units%nktv2p
                rate = 0
            end if
            if (r%ts%active()) s%ecouple = r%ecouple
            call r%out%sample(s, s%etotal, [real(stats%events, dp), real(stats%pair_events, dp), rate, &
                                            real(stats%bounces, dp), real(stats%captures, dp), real(stats%escapes, dp), &
                                            map_count(r)])
            stats%e_last = s%etotal - s%ecouple       ! (with a thermostat: econserve)
            r%ke_int = 0; r%virial = 0; r%t_last = t; r%core_last = stats%core
            call eng%timers%stop(t_output)
        end associate
    end subroutine write_sample

    real(dp) function map_count(r)
        type(ed_run_t), intent(in) :: r
        map_count = 0
        if (r%tab%has_steps) map_count = real(r%map%count(), dp)
    end function map_count

    !> The thermo sample at t from every atom (the same sums on every rank).
    function sample(r, t) result(s)
        type(ed_run_t), intent(in) :: r
        real(dp), intent(in) :: t
        type(thermo_sample_t) :: s
        real(dp) :: rr(3), pl(6), ke, dof
        integer :: i
        pl = 0; ke = 0
        associate (x => r%x, v => r%v, m => r%m)
            do i = 1, r%n
                rr = x(:, i) + v(:, i)*(t - r%tl(i)) + r%img(:, i)*r%length
                ke = ke + m(i)*(v(1, i)**2 + v(2, i)**2 + v(3, i)**2)
                pl(1:3) = pl(1:3) + m(i)*v(:, i)
                pl(4:6) = pl(4:6) + m(i)*[rr(2)*v(3, i) - rr(3)*v(2, i), rr(3)*v(1, i) - rr(1)*v(3, i), &
                                          rr(1)*v(2, i) - rr(2)*v(1, i)]
            end do
        end associate
        s%step = r%stats%events; s%time = t
        s%ke = 0.5_dp*ke*r%eng%units%mvv2e
        s%pe = r%pe
        s%etotal = s%ke + s%pe
        s%momentum = pl(1:3); s%angular = pl(4:6)
        dof = 3*real(r%n, dp) - 3
        if (r%ts%active()) dof = r%eng%ndof         ! (Andersen: the total momentum is not held)
        s%temp = 0
        if (dof > 0) s%temp = 2*s%ke/(dof*r%eng%units%boltz)
    end function sample

    subroutine write_frame(r, t)
        type(ed_run_t), intent(inout) :: r
        real(dp), intent(in) :: t
        type(thermo_sample_t) :: s
        character(len=16), parameter :: names(3) = [character(len=16) :: 'events', 'collisions', 'captured_pairs']
        call put_state(r, t)
        s = sample(r, t)
        call r%out%frame(r%eng, r%stats%events, t, s, names, &
                         [real(r%stats%events, dp), real(r%stats%pair_events, dp), map_count(r)])
    end subroutine write_frame

    !> This rank's atoms in the engine take the state at t (for frames, checkpoints and the final
    !> atoms file).
    subroutine put_state(r, t)
        type(ed_run_t), intent(inout) :: r
        real(dp), intent(in) :: t
        integer :: k, g, d
        real(dp) :: xt(3), s
        associate (atoms => r%eng%atoms)
            do k = 1, atoms%nlocal
                g = r%slot_of_id(int(atoms%id(k)))
                xt = r%x(:, g) + r%v(:, g)*(t - r%tl(g))
                atoms%image(:, k) = r%img(:, g)
                do d = 1, 3        ! (an atom due to cross the box face at t may lie on it)
                    s = floor((xt(d) - r%eng%box%lo(d))*r%inv_len(d))
                    xt(d) = xt(d) - s*r%length(d)
                    atoms%image(d, k) = atoms%image(d, k) + int(s)
                end do
                atoms%x(:, k) = xt
                atoms%v(:, k) = r%v(:, g)
                atoms%f(:, k) = 0
            end do
        end associate
    end subroutine put_state

    real(dp) function kinetic(r)
        type(ed_run_t), intent(in) :: r
        integer :: i
        kinetic = 0
        do i = 1, r%n
            kinetic = kinetic + 0.5_dp*r%m(i)*sum(r%v(:, i)**2)
        end do
    end function kinetic

end module terrace_event_driven
