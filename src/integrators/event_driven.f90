!> Event-driven molecular dynamics of stepped pair potentials (hard spheres, square wells).
!>
!> Atoms move in straight lines between events. Each atom keeps its position at its own time
!> (tl, a delayed state): an event brings only its atoms to the event time. The events:
!>  - pair events: a pair crosses one of its radii (terrace_stepped_pair: the time is a root of a
!>    quadratic in closed form; the crossing changes the two velocities along the line of centres,
!>    by -dU of normal kinetic energy, or reflects the pair when it cannot pay);
!>  - cell crossings: an atom leaves its cell of the grid (terrace_event_cells; cells of at least
!>    the largest radius, so that partners are found in the 27 neighbouring cells);
!>  - the run's schedule (thermo samples, trajectory frames, the end) as one more slot of the queue.
!> The queue (terrace_event_queue) holds one slot per atom: the atom's earliest predicted event.
!> An event re-predicts only its atoms (over their neighbouring cells): O(neighbours + log N). A
!> slot whose partner has had an event since the prediction (per-atom event counters) is stale;
!> it is predicted again when it comes to the top (lazy invalidation).
!>
!> Pairs inside a well are remembered with their region (terrace_pair_map), so that a pair right
!> at a radius after crossing it is never taken for one outside it (round-off cannot make it cross
!> twice). Outputs are taken at exact times from the delayed states (x + v (t - tl)).
!>
!> Ranks: every rank holds all atoms and runs the same sequence of events (the same arithmetic in
!> the same order), so that every rank count gives the same results; rank 0 writes the thermo
!> CSV, and each rank writes its own atoms' rows of a trajectory frame.
module terrace_event_driven
    use terrace_kinds, only: dp, i8
    use terrace_text, only: int_text, real_text
    use terrace_engine, only: engine_t
    use terrace_thermo, only: thermo_writer_t
    use terrace_trajectory, only: trajectory_t
    use terrace_observables, only: thermo_sample_t
    use terrace_stepped_pair, only: stepped_table_t, inward_time, outward_time, collide, no_event
    use terrace_stepped_potential, only: stepped_table_of
    use terrace_event_queue, only: event_queue_t
    use terrace_event_cells, only: event_cells_t
    use terrace_pair_map, only: pair_map_t
    use terrace_velocities, only: atom_mass, hash_uniform
    use terrace_mpi_env, only: world, min_all
    use terrace_errors, only: stop_all, check_all
    use terrace_timers, only: t_pair, t_output
    use mpi_f08, only: MPI_Allgatherv, MPI_Allgather, MPI_INTEGER, MPI_INTEGER8, MPI_DOUBLE_PRECISION
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
    end type ed_params_t

    public :: run_event_driven, check_event_driven_start

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

    !> Run from t = 0 to p%t_end with thermo samples every p%sample_dt and frames every p%frame_dt
    !> (0: none). Collective (every rank runs the same events).
    subroutine run_event_driven(eng, p, thermo, traj, stats)
        type(engine_t), intent(inout) :: eng
        type(ed_params_t), intent(in) :: p
        type(thermo_writer_t), intent(inout) :: thermo
        type(trajectory_t), intent(inout) :: traj
        type(ed_stats_t), intent(out) :: stats

        type(stepped_table_t) :: tab
        type(event_queue_t) :: q
        type(event_cells_t) :: cells
        type(pair_map_t) :: map
        real(dp), allocatable :: x(:, :), v(:, :), tl(:), m(:), ev_t(:)
        integer, allocatable :: typ(:), img(:, :), ev_kind(:), ev_partner(:), ev_code(:)
        integer, allocatable :: id_of(:), slot_of_id(:)      !< atom number (cell order) <-> id
        integer(i8), allocatable :: cnt(:), ev_pcount(:)
        real(dp) :: length(3), inv_len(3), t, pe, ke_run, ke_int, t_ke, virial, t_last
        real(dp) :: t_next_sample, t_next_frame
        integer(i8) :: n_sample, n_frame, core_last
        integer :: n, slot, sched_slot, partner, code
        logical :: found, ok

        call stepped_table_of(eng%pot, tab, found)
        call check_all(found, 'event_driven: the potential is not a stepped one')
        length = eng%box%length
        inv_len = 1/length
        call gather_atoms()
        if (p%temperature >= 0 .and. .not. eng%restarted) call same_start_velocities()
        sched_slot = n + 1
        call cells%init(eng%box%lo, length, tab%rmax, n, ok)
        call check_all(ok, p%where_cells//': the box must be at least 3 interaction radii '// &
                       'long in x, y and z for event-driven integration (largest radius: '//real_text(tab%rmax)//')')
        call place_atoms()
        call find_regions()
        ke_run = kinetic(); ke_int = 0; t_ke = 0; virial = 0; t_last = 0; core_last = 0
        allocate (ev_t(n), ev_kind(n), ev_partner(n), ev_code(n), ev_pcount(n), cnt(n))
        cnt = 0; ev_kind = kind_cell; ev_partner = 0; ev_code = 0; ev_pcount = 0
        call q%init(n + 1)
        call eng%timers%start(t_pair)
        do slot = 1, n
            call predict(slot, 0.0_dp)
        end do
        call eng%timers%stop(t_pair)
        n_sample = 1; n_frame = 1
        t_next_sample = huge(1.0_dp); t_next_frame = huge(1.0_dp)
        if (p%sample_dt > 0) t_next_sample = snapped(p%sample_dt, p%sample_dt)
        if (p%frame_dt > 0) t_next_frame = snapped(p%frame_dt, p%frame_dt)
        call write_sample(0.0_dp)
        stats%e_first = stats%e_last
        if (p%frame_dt > 0) call write_frame(0.0_dp)
        call q%set(sched_slot, min(t_next_sample, t_next_frame, p%t_end))

        call eng%timers%start(t_pair)
        do
            slot = q%top()
            t = q%t(slot)
            if (slot == sched_slot) then
                call eng%timers%stop(t_pair)
                if (schedule(t)) exit
                call eng%timers%start(t_pair)
                cycle
            end if
            stats%events = stats%events + 1
            if (ev_kind(slot) == kind_cell) then
                call cell_event(slot, t)
            else if (cnt(ev_partner(slot)) /= ev_pcount(slot)) then
                stats%stale = stats%stale + 1
                call predict(slot, t)
            else
                partner = ev_partner(slot); code = ev_code(slot)      ! (copies: predict rewrites the slot)
                call pair_event(slot, partner, code, t)
            end if
        end do
        stats%time = p%t_end
        call put_state(p%t_end)
        eng%pe = pe

    contains

        !> Every rank gets every atom, in id order (ids 1 .. natoms).
        subroutine gather_atoms()
            integer, allocatable :: counts(:), displ(:), ti(:), ii(:, :)
            integer(i8), allocatable :: ids(:)
            real(dp), allocatable :: xx(:, :), vv(:, :), mm(:), mm_local(:)
            integer :: nl, r, k
            integer(i8) :: g
            nl = eng%atoms%nlocal
            n = int(eng%natoms)
            allocate (counts(world%nprocs), displ(world%nprocs))
            call MPI_Allgather(nl, 1, MPI_INTEGER, counts, 1, MPI_INTEGER, world%comm)
            displ(1) = 0
            do r = 2, world%nprocs
                displ(r) = displ(r - 1) + counts(r - 1)
            end do
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
            allocate (x(3, n), v(3, n), tl(n), m(n), typ(n), img(3, n))
            tl = 0
            do k = 1, n
                g = ids(k)
                call check_all(g >= 1 .and. g <= n, eng%source//': event-driven integration needs atom ids 1 .. N')
                x(:, g) = xx(:, k); v(:, g) = vv(:, k); m(g) = mm(k); typ(g) = ti(k); img(:, g) = ii(:, k)
            end do
        end subroutine gather_atoms

        !> &system temperature: the velocities drawn again as the scene builder draws them (the same
        !> normal deviates keyed by seed, id and component; drift removed; scaled to T with 3N - 3
        !> degrees of freedom; reversed with reverse_velocities), but with the sums taken over all
        !> atoms in id order on every rank: the scene builder's sums over ranks differ in their
        !> last bits between rank counts, which the dynamics' chaos would amplify.
        subroutine same_start_velocities()
            integer :: g, d
            real(dp) :: u1, u2, ptot(3), mtot, ke, t_now, temp
            real(dp), parameter :: two_pi = 8*atan(1.0_dp)
            temp = p%temperature
            do g = 1, n
                do d = 1, 3
                    u1 = hash_uniform(p%seed, int(g, i8), 2*d - 1)
                    u2 = hash_uniform(p%seed, int(g, i8), 2*d)
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
            if (p%reverse_velocities) v = -v
        end subroutine same_start_velocities

        !> Wrap the positions into the box, number the atoms in the order of their cells (atoms
        !> that meet sit close in memory; slot_of_id and id_of map between ids and these numbers)
        !> and put every atom into its cell.
        subroutine place_atoms()
            integer :: i, d, k, c(3)
            integer, allocatable :: cell_of(:), start(:), perm(:), ic(:, :)
            real(dp) :: s
            allocate (cell_of(n), ic(3, n), start(product(cells%nc) + 1), perm(n), id_of(n), slot_of_id(n))
            do i = 1, n
                do d = 1, 3
                    s = floor((x(d, i) - eng%box%lo(d))*inv_len(d))
                    x(d, i) = x(d, i) - s*length(d)
                    img(d, i) = img(d, i) + int(s)
                    c(d) = int((x(d, i) - eng%box%lo(d))/cells%w(d))
                    c(d) = min(max(c(d), 0), cells%nc(d) - 1)
                end do
                ic(:, i) = c
                cell_of(i) = cells%index(c)
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
            x = x(:, perm); v = v(:, perm); m = m(perm); typ = typ(perm); img = img(:, perm)
            ic = ic(:, perm)
            do k = 1, n
                id_of(k) = perm(k)
                slot_of_id(perm(k)) = k
            end do
            do i = n, 1, -1          ! (inserted last to first: each cell's list runs in id order)
                call cells%insert(i, ic(:, i))
            end do
        end subroutine place_atoms

        !> Regions of the pairs inside a radius at the start (overlaps of hard cores are refused),
        !> and the potential energy.
        subroutine find_regions()
            integer :: i, j, s, c, nb(27)
            real(dp) :: dx(3)
            integer(i8) :: inside
            pe = 0
            inside = 0
            if (tab%has_steps) call map%init(int(n, i8), int(n, i8)*4)
            do i = 1, n
                call neighbour_cells(i, nb)
                do c = 1, 27
                    j = cells%head(nb(c))
                    do while (j > 0)
                        if (j > i) then
                            dx = x(:, i) - x(:, j)
                            dx = dx - length*anint(dx*inv_len)
                            s = tab%region_of(typ(i), typ(j), sum(dx**2))
                            if (s == tab%nr(typ(i), typ(j))) call stop_all(eng%source//': overlapping hard cores '// &
                                '(atoms '//int_text(id_of(i))//' and '//int_text(id_of(j))//' closer than their diameter)')
                            if (s > 0) then
                                call map%put(i, j, s)
                                pe = pe + tab%u(s, typ(i), typ(j))
                                inside = inside + 1
                            end if
                        end if
                        j = cells%nxt(j)
                    end do
                end do
            end do
        end subroutine find_regions

        !> The 27 cells around atom i's cell (periodic).
        pure subroutine neighbour_cells(i, nb)
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

        !> Atom i's earliest event after t (its cell crossing or a crossing of a radius with an atom
        !> of the 27 cells around it) into its slot.
        subroutine predict(i, t)
            integer, intent(in) :: i
            real(dp), intent(in) :: t
            real(dp) :: xi(3), dx(3), dv(3), best, dt, b, rsq
            integer :: nb(27), c, j, dir, s, ti, tj, nr, best_j, best_code
            xi = x(:, i) + v(:, i)*(t - tl(i))
            call cells%crossing(i, xi, v(:, i), best, dir)
            best_j = 0; best_code = dir
            call neighbour_cells(i, nb)
            ti = typ(i)
            do c = 1, 27
                j = cells%head(nb(c))
                do while (j > 0)
                    if (j /= i) then
                        dx = xi - (x(:, j) + v(:, j)*(t - tl(j)))
                        dx = dx - length*anint(dx*inv_len)
                        dv = v(:, i) - v(:, j)
                        tj = typ(j)
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
                    end if
                    j = cells%nxt(j)
                end do
            end do
            ev_code(i) = best_code; ev_partner(i) = best_j
            if (best_j > 0) then
                ev_kind(i) = kind_pair; ev_pcount(i) = cnt(best_j)
            else
                ev_kind(i) = kind_cell
            end if
            ev_t(i) = t + best
            call q%set(i, ev_t(i))
        end subroutine predict

        !> The pair (i, j) crosses radius |code| at t, inward (code > 0) or outward (code < 0).
        subroutine pair_event(i, j, code, t)
            integer, intent(in) :: i, j, code
            real(dp), intent(in) :: t
            real(dp) :: dx(3), du, w, ke_old
            integer :: k, nr, s_new, ti, tj
            logical :: crossed
            x(:, i) = x(:, i) + v(:, i)*(t - tl(i)); tl(i) = t
            x(:, j) = x(:, j) + v(:, j)*(t - tl(j)); tl(j) = t
            dx = x(:, i) - x(:, j)
            dx = dx - length*anint(dx*inv_len)
            ti = typ(i); tj = typ(j)
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
            call collide(dx, v(:, i), v(:, j), m(i), m(j), du/eng%units%mvv2e, crossed, w)
            ke_int = ke_int + ke_run*(t - t_ke); t_ke = t
            ke_run = ke_run + (0.5_dp*(m(i)*sum(v(:, i)**2) + m(j)*sum(v(:, j)**2)) - ke_old)
            virial = virial + w
            stats%pair_events = stats%pair_events + 1
            if (crossed) then
                pe = pe + du
                call map%put(i, j, s_new)
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
            cnt(i) = cnt(i) + 1; cnt(j) = cnt(j) + 1
            call predict(i, t)
            call predict(j, t)
        end subroutine pair_event

        !> Atom i leaves its cell through face ev_code(i) at t (across the box: wrapped, image counted).
        subroutine cell_event(i, t)
            integer, intent(in) :: i
            real(dp), intent(in) :: t
            integer :: d, c(3)
            stats%cell_events = stats%cell_events + 1
            x(:, i) = x(:, i) + v(:, i)*(t - tl(i)); tl(i) = t
            d = abs(ev_code(i))
            c = cells%ic(:, i)
            c(d) = c(d) + sign(1, ev_code(i))
            if (c(d) >= cells%nc(d)) then
                c(d) = 0; x(d, i) = x(d, i) - length(d); img(d, i) = img(d, i) + 1
            else if (c(d) < 0) then
                c(d) = cells%nc(d) - 1; x(d, i) = x(d, i) + length(d); img(d, i) = img(d, i) - 1
            end if
            call cells%remove(i)
            call cells%insert(i, c)
            call predict(i, t)
        end subroutine cell_event

        !> A scheduled time; one within 1e-9 intervals of the end is the end (no second sample
        !> a rounding error after the last one).
        pure real(dp) function snapped(time, interval)
            real(dp), intent(in) :: time, interval
            snapped = time
            if (abs(p%t_end - time) <= 1.0e-9_dp*interval) snapped = p%t_end
        end function snapped

        !> The schedule slot at t: samples, frames, the end (.true.). Then its next time.
        logical function schedule(t) result(done)
            real(dp), intent(in) :: t
            logical :: sample_due, frame_due
            done = t >= p%t_end
            sample_due = t >= t_next_sample .or. done
            frame_due = t >= t_next_frame
            if (sample_due) then
                call write_sample(t)
                if (t >= t_next_sample) then
                    n_sample = n_sample + 1
                    t_next_sample = snapped(n_sample*p%sample_dt, p%sample_dt)
                end if
            end if
            if (frame_due) then
                call write_frame(t)
                n_frame = n_frame + 1
                t_next_frame = snapped(n_frame*p%frame_dt, p%frame_dt)
            end if
            if (.not. done) call q%set(sched_slot, min(t_next_sample, t_next_frame, p%t_end))
        end function schedule

        subroutine write_sample(t)
            real(dp), intent(in) :: t
            type(thermo_sample_t) :: s
            real(dp) :: tau, rate
            call eng%timers%start(t_output)
            s = sample(t)
            tau = t - t_last
            ke_int = ke_int + ke_run*(t - t_ke); t_ke = t
            if (tau > 0) then
                s%press = (2*ke_int + virial)/tau*eng%units%mvv2e/(3*eng%box%volume())*eng%units%nktv2p
                rate = 2*real(stats%core - core_last, dp)/(n*tau)
            else
                s%press = 2*s%ke/(3*eng%box%volume())*eng%units%nktv2p
                rate = 0
            end if
            call thermo%write(s, [real(stats%events, dp), real(stats%pair_events, dp), rate, &
                                  real(stats%bounces, dp), real(stats%captures, dp), real(stats%escapes, dp), &
                                  real(map_count(), dp)])
            stats%e_last = s%etotal
            ke_int = 0; virial = 0; t_last = t; core_last = stats%core
            call eng%timers%stop(t_output)
        end subroutine write_sample

        real(dp) function map_count()
            map_count = 0
            if (tab%has_steps) map_count = real(map%count(), dp)
        end function map_count

        !> The thermo sample at t from every atom (the same sums on every rank).
        function sample(t) result(s)
            real(dp), intent(in) :: t
            type(thermo_sample_t) :: s
            real(dp) :: r(3), pl(6), ke, dof
            integer :: i
            pl = 0; ke = 0
            do i = 1, n
                r = x(:, i) + v(:, i)*(t - tl(i)) + img(:, i)*length
                ke = ke + m(i)*(v(1, i)**2 + v(2, i)**2 + v(3, i)**2)
                pl(1:3) = pl(1:3) + m(i)*v(:, i)
                pl(4:6) = pl(4:6) + m(i)*[r(2)*v(3, i) - r(3)*v(2, i), r(3)*v(1, i) - r(1)*v(3, i), &
                                          r(1)*v(2, i) - r(2)*v(1, i)]
            end do
            s%step = stats%events; s%time = t
            s%ke = 0.5_dp*ke*eng%units%mvv2e
            s%pe = pe
            s%etotal = s%ke + s%pe
            s%momentum = pl(1:3); s%angular = pl(4:6)
            dof = 3*real(n, dp) - 3
            s%temp = 0
            if (dof > 0) s%temp = 2*s%ke/(dof*eng%units%boltz)
        end function sample

        subroutine write_frame(t)
            real(dp), intent(in) :: t
            type(thermo_sample_t) :: s
            character(len=512) :: msg
            character(len=16), parameter :: names(3) = [character(len=16) :: 'events', 'collisions', 'captured_pairs']
            call eng%timers%start(t_output)
            call put_state(t)
            s = sample(t)
            call traj%write(stats%events, t, eng%atoms, s, ok, msg, names, &
                            [real(stats%events, dp), real(stats%pair_events, dp), map_count()])
            call check_all(ok, trim(msg))
            call eng%timers%stop(t_output)
        end subroutine write_frame

        !> This rank's atoms in the engine take the state at t (for frames and the final atoms file).
        subroutine put_state(t)
            real(dp), intent(in) :: t
            integer :: k, g, d
            real(dp) :: xt(3), s
            do k = 1, eng%atoms%nlocal
                g = slot_of_id(int(eng%atoms%id(k)))
                xt = x(:, g) + v(:, g)*(t - tl(g))
                eng%atoms%image(:, k) = img(:, g)
                do d = 1, 3        ! (an atom due to cross the box face at t may lie on it)
                    s = floor((xt(d) - eng%box%lo(d))*inv_len(d))
                    xt(d) = xt(d) - s*length(d)
                    eng%atoms%image(d, k) = eng%atoms%image(d, k) + int(s)
                end do
                eng%atoms%x(:, k) = xt
                eng%atoms%v(:, k) = v(:, g)
                eng%atoms%f(:, k) = 0
            end do
        end subroutine put_state

        real(dp) function kinetic()
            integer :: i
            kinetic = 0
            do i = 1, n
                kinetic = kinetic + 0.5_dp*m(i)*sum(v(:, i)**2)
            end do
        end function kinetic

    end subroutine run_event_driven

end module terrace_event_driven
