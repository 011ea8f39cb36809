!> Energy minimization of the atom positions at a fixed box, written in the engine's operations
!> (compute_forces, rebuild / refresh_ghosts, the atoms' x, v, f), with LAMMPS `minimize`'s
!> stopping criteria, tested in this order after each iteration:
!>   'energy tolerance'       |E_k - E_{k-1}| < etol (|E_k| + |E_{k-1}| + 1e-8) / 2
!>   'force tolerance'        the 2-norm of the global force vector < ftol
!>   'max iterations'         max_iterations iterations
!>   'max force evaluations'  max_evaluations force passes
!>   'linesearch alpha is zero'  (CG) no step along the search direction lowers the energy
!> Styles:
!>   'cg'    Polak-Ribiere conjugate gradients (beta = max(0, (f.f - f.f_old) / f_old.f_old), the
!>           direction reset to the force when it is no longer a descent direction). Line search:
!>           a first step that moves no coordinate more than dmax, then the secant on the
!>           directional derivative f.h (exact for a quadratic energy) with halving while the energy
!>           rises above the start's by more than its round-off.
!>   'fire'  FIRE (Bitzek et al., PRL 97, 170201 (2006)): MD with semi-implicit Euler steps whose
!>           velocity is mixed towards the force, v = (1 - a) v + a |v| f / |f|; after Nmin = 5
!>           steps with P = f.v > 0 the step grows (x 1.1, at most 10 dt) and a shrinks (x 0.99);
!>           when P <= 0 the step shrinks (x 0.5), a = 0.1, the positions go back half a step
!>           and v = 0. No coordinate moves more than dmax in one step. The atoms' velocities are
!>           restored at the end (dynamics that follow start from the deck's velocities).
!> Global sums (dot products, norms) are taken with one reduction each; every rank takes the
!> same decisions. A thermo row per iteration: iteration, energy, largest force component, the
!> force 2-norm (rank 0 writes it to `unit`, unless it is `no_unit`).
module terrace_minimize
    use terrace_kinds, only: dp, i8
    use terrace_engine, only: engine_t
    use terrace_scene_plan, only: pair_all
    use terrace_mpi_env, only: world, sum_all, max_all, gather_counts
    implicit none
    private

    !> What a minimization is made from (the run's units applied).
    type, public :: minimize_params_t
        character(len=8) :: style = 'cg'
        real(dp) :: etol = 0, ftol = 0
        integer(i8) :: max_iterations = 10000, max_evaluations = 100000
        real(dp) :: dt = 0.001_dp                !< FIRE's first time step
        real(dp) :: dmax = 0.1_dp                !< largest move of a coordinate in one step (length)
        !> 'none'; 'iso': also the box's volume (isotropically); 'aniso': also the box's edges, each
        !> driven by its own diagonal pressure; both to pressure
        character(len=8) :: box_relax = 'none'
        real(dp) :: pressure = 0                 !< box_relax: target pressure (the run's unit)
    end type minimize_params_t

    !> What it did: the criterion that stopped it (LAMMPS's words), counts and energies.
    type, public :: minimize_result_t
        character(len=:), allocatable :: criterion
        integer(i8) :: iterations = 0, evaluations = 0
        real(dp) :: e_initial = 0, e_final = 0, fnorm2 = 0, fmax = 0
        integer :: box_steps = 0                 !< box_relax: box changes made
        real(dp) :: pressure = 0                 !< box_relax: the final virial pressure (the run's unit)
        real(dp) :: pressure_diag(3) = 0         !< box_relax = 'aniso': the final static P_aa (the run's unit)
    end type minimize_result_t

    real(dp), parameter :: eps_energy = 1.0e-8_dp
    !> run_minimize's unit when no rows are written (newunit= numbers are negative: not -1)
    integer, parameter, public :: no_unit = -huge(1)

    !> The conjugate-gradient search's per-atom arrays, in the owned atoms' rows: ids, the unwrapped
    !> start of the line search, the direction h and the previous force g. A list rebuild may
    !> migrate and reorder atoms: remap puts the rows back in the atoms' new order.
    type :: cg_rows_t
        integer(i8), allocatable :: id(:)
        real(dp), allocatable :: x0(:, :), h(:, :), g(:, :)
    end type cg_rows_t

    !> What the relaxations of one minimization share: its parameters, the unit of its thermo rows,
    !> the engine's force evaluations before it and what it did so far.
    type :: minimization_t
        type(minimize_params_t) :: p
        integer :: unit = no_unit
        integer(i8) :: ev0 = 0
        type(minimize_result_t) :: res
        integer(i8) :: done = 0                  !< box_relax: the atom relaxations' iterations so far
    end type minimization_t

    public :: run_minimize

contains

    subroutine run_minimize(eng, p, unit, res)
        type(engine_t), intent(inout) :: eng
        type(minimize_params_t), intent(in) :: p
        integer, intent(in) :: unit
        type(minimize_result_t), intent(out) :: res
        type(minimization_t) :: m
        logical :: diag_wanted
        m%p = p; m%unit = unit; m%ev0 = eng%force_evaluations
        diag_wanted = eng%want_virial_diag         ! box_relax = 'aniso' needs the virial's diagonal
        eng%want_virial_diag = diag_wanted .or. p%box_relax == 'aniso'
        call eng%compute_forces(.true.)
        m%res%e_initial = eng%pe
        if (unit /= no_unit .and. world%rank == 0) write (unit, '(a)') 'iteration,pe,fmax,fnorm'
        call write_row(eng, 0_i8, unit)
        select case (trim(p%box_relax))
        case ('iso')
            call relax_box(eng, m)
        case ('aniso')
            call relax_box_aniso(eng, m)
        case default
            call relax_atoms(eng, m)
        end select
        m%res%e_final = eng%pe
        m%res%evaluations = eng%force_evaluations - m%ev0
        m%res%fnorm2 = sqrt(dot_ff(eng))
        m%res%fmax = fmax_all(eng)
        res = m%res
        eng%want_virial_diag = diag_wanted
    end subroutine run_minimize

    subroutine relax_atoms(eng, m)
        type(engine_t), intent(inout) :: eng
        type(minimization_t), intent(inout) :: m
        m%res%iterations = 0
        if (m%p%ftol > 0 .and. dot_ff(eng) < m%p%ftol**2) then
            m%res%criterion = 'force tolerance'       ! already there
            return
        end if
        select case (trim(m%p%style))
        case ('fire')
            call fire(eng, m)
        case default
            call cg(eng, m)
        end select
    end subroutine relax_atoms

    !> One atom relaxation of a box relaxation, with what is left of the iteration budget: m%done
    !> counts the iterations across the relaxations (and res%iterations reports it); spent: the budget
    !> ran out (max iterations or max force evaluations).
    subroutine relax_atoms_within(eng, m, spent)
        type(engine_t), intent(inout) :: eng
        type(minimization_t), intent(inout) :: m
        logical, intent(out) :: spent
        integer(i8) :: budget
        budget = m%p%max_iterations
        m%p%max_iterations = max(1_i8, budget - m%done)
        call relax_atoms(eng, m)
        m%p%max_iterations = budget
        m%done = m%done + m%res%iterations
        m%res%iterations = m%done
        spent = m%res%criterion == 'max iterations' .or. m%res%criterion == 'max force evaluations'
    end subroutine relax_atoms_within

    !> box_relax: the atoms relaxed at a fixed box, then the volume changed (isotropically, through
    !> engine%scale_box) towards the target pressure, until the static pressure W / (d V) is
    !> within ftol / V of the target (the force on ln V below ftol) after an atom relaxation.
    !> The volume steps are secants on ln V of P(ln V) - P0 (the first one from a bulk modulus
    !> of 1 eV/A^3 in metal units, 100 in lj, 1e11 Pa in si); iterations count on across the atom
    !> relaxations.
    subroutine relax_box(eng, m)
        type(engine_t), intent(inout) :: eng
        type(minimization_t), intent(inout) :: m
        logical :: spent
        real(dp) :: p0, g, g_old, eps, eps_old, deps, b0, v, mu
        integer :: k, d
        p0 = m%p%pressure/eng%units%nktv2p
        b0 = eng%units%bulk_modulus_guess
        g_old = 0; eps_old = 0
        do k = 1, 200
            call relax_atoms_within(eng, m, spent)
            v = eng%box%volume()
            g = eng%virial/(eng%box%dimension*v) - p0         ! > 0: the box wants to grow
            eps = log(v)
            if (abs(g)*v < max(m%p%ftol, 1.0e-300_dp) .or. spent) exit
            if (k == 1 .or. g == g_old) then
                deps = g/b0
            else
                deps = -g*(eps - eps_old)/(g - g_old)
            end if
            deps = max(-0.05_dp, min(0.05_dp, deps))
            if (abs(deps) < 1.0e-15_dp) exit
            g_old = g; eps_old = eps
            mu = exp(deps/eng%box%dimension)
            call eng%scale_box([(merge(mu, 1.0_dp, d <= eng%box%dimension), d = 1, 3)], velocities=.false.)
            call eng%compute_forces(.true.)
            m%res%box_steps = m%res%box_steps + 1
        end do
        m%res%pressure = eng%virial/(eng%box%dimension*eng%box%volume())*eng%units%nktv2p
    end subroutine relax_box

    !> box_relax = 'aniso': as relax_box, with the box's edges as independent degrees of freedom
    !> (LAMMPS's fix box/relax aniso): after each atom relaxation the static diagonal pressure
    !> g_a = W_aa / V - P0 (W_aa the virial's diagonal, which the force passes give while this runs),
    !> and the edges' log-strains eps_a = ln L_a take a quasi-Newton step deps = -J^-1 g, J the
    !> Jacobian dg/deps: first -b0 I (the bulk-modulus guess), then Broyden's update after each step,
    !> J += (dg - J ds) ds^T / ds.ds (in one dimension: relax_box's secant). Steps at most 0.05 per
    !> edge; each edge scaled through engine%scale_box (positions and the domain with it). Stops when
    !> the force on the log-strains, V |g| (2-norm), is below ftol, or the step below 1e-15.
    subroutine relax_box_aniso(eng, m)
        type(engine_t), intent(inout) :: eng
        type(minimization_t), intent(inout) :: m
        logical :: spent
        real(dp) :: p0, b0, v, g(3), g_old(3), deps(3), jac(3, 3), dg(3), jd(3), mu(3), ds2
        integer :: k, nd
        logical :: ok
        nd = eng%box%dimension
        p0 = m%p%pressure/eng%units%nktv2p
        b0 = eng%units%bulk_modulus_guess
        call guess(jac)
        g = 0; g_old = 0; deps = 0
        do k = 1, 200
            call relax_atoms_within(eng, m, spent)
            v = eng%box%volume()
            g(1:nd) = eng%virial_diag(1:nd)/v - p0          ! > 0: the box wants to grow along a
            if (norm2(g(1:nd))*v < max(m%p%ftol, 1.0e-300_dp) .or. spent) exit
            if (k > 1) then                                   ! Broyden's update from the last step
                dg = g - g_old
                jd = matmul(jac, deps)
                ds2 = sum(deps(1:nd)**2)
                if (ds2 > 0) jac = jac + spread(dg - jd, 2, 3)*spread(deps, 1, 3)/ds2
            end if
            deps = 0
            call solve(jac(1:nd, 1:nd), -g(1:nd), deps(1:nd), ok)
            if (.not. ok) then                                ! start again from the guess
                call guess(jac)
                deps(1:nd) = g(1:nd)/b0
            end if
            deps = max(-0.05_dp, min(0.05_dp, deps))
            if (maxval(abs(deps)) < 1.0e-15_dp) exit
            g_old = g
            mu = exp(deps)
            call eng%scale_box(mu, velocities=.false.)
            call eng%compute_forces(.true.)
            m%res%box_steps = m%res%box_steps + 1
        end do
        m%res%pressure = eng%virial/(nd*eng%box%volume())*eng%units%nktv2p
        m%res%pressure_diag = 0
        m%res%pressure_diag(1:nd) = eng%virial_diag(1:nd)/eng%box%volume()*eng%units%nktv2p
    contains
        subroutine guess(j)
            real(dp), intent(out) :: j(3, 3)
            integer :: a
            j = 0
            do a = 1, 3
                j(a, a) = -b0
            end do
        end subroutine guess
    end subroutine relax_box_aniso

    !> x with a x = b for a small dense matrix (Gaussian elimination, partial pivoting); ok = .false.
    !> for a singular matrix.
    subroutine solve(a, b, x, ok)
        real(dp), intent(in) :: a(:, :), b(:)
        real(dp), intent(out) :: x(:)
        logical, intent(out) :: ok
        real(dp) :: m(size(b), size(b) + 1), row(size(b) + 1)
        integer :: n, i, j, piv
        n = size(b)
        m(:, 1:n) = a; m(:, n + 1) = b
        x = 0
        ok = .false.
        do i = 1, n
            piv = i - 1 + maxloc(abs(m(i:n, i)), 1)
            if (.not. (abs(m(piv, i)) > 0)) return
            row = m(i, :); m(i, :) = m(piv, :); m(piv, :) = row
            do j = i + 1, n
                m(j, :) = m(j, :) - m(j, i)/m(i, i)*m(i, :)
            end do
        end do
        do i = n, 1, -1
            x(i) = (m(i, n + 1) - sum(m(i, i + 1:n)*x(i + 1:n)))/m(i, i)
        end do
        ok = all(abs(x) <= huge(1.0_dp))
    end subroutine solve

    !> Positions moved: ghosts refreshed or the list rebuilt when due, then forces and energy.
    subroutine evaluate(eng, iter)
        type(engine_t), intent(inout) :: eng
        integer(i8), intent(in) :: iter
        if (eng%plan%pair_mode == pair_all) then
            call eng%refresh_ghosts()
        else if (eng%list%rebuild_due(eng%atoms, iter, .false.)) then
            call eng%rebuild()
        else
            call eng%refresh_ghosts()
        end if
        call eng%compute_forces(.true.)
    end subroutine evaluate

    !> The criterion met after iteration iter (energies before and after it), or ''.
    function criterion(eng, m, iter, e_old, e_new) result(c)
        type(engine_t), intent(inout) :: eng
        type(minimization_t), intent(in) :: m
        integer(i8), intent(in) :: iter
        real(dp), intent(in) :: e_old, e_new
        character(len=:), allocatable :: c
        c = ''
        if (m%p%etol > 0 .and. abs(e_new - e_old) < m%p%etol*0.5_dp*(abs(e_new) + abs(e_old) + eps_energy)) then
            c = 'energy tolerance'
        else if (m%p%ftol > 0 .and. dot_ff(eng) < m%p%ftol**2) then
            c = 'force tolerance'
        else if (iter >= m%p%max_iterations) then
            c = 'max iterations'
        else if (eng%force_evaluations - m%ev0 >= m%p%max_evaluations) then
            c = 'max force evaluations'
        end if
    end function criterion

    subroutine cg(eng, m)
        type(engine_t), intent(inout) :: eng
        type(minimization_t), intent(inout) :: m
        type(cg_rows_t) :: r
        real(dp) :: e_old, s(3), beta, hf
        integer(i8) :: iter
        integer :: n
        logical :: ok
        n = eng%atoms%nlocal
        allocate (r%id(n), r%h(3, n), r%g(3, n))
        r%id = eng%atoms%id(1:n)
        r%h = eng%atoms%f(:, 1:n)
        r%g = r%h
        allocate (r%x0(3, n))
        iter = 0
        do
            iter = iter + 1
            e_old = eng%pe
            call line_search(eng, m%p, r, ok)
            call write_row(eng, iter, m%unit)
            m%res%iterations = iter
            if (.not. ok) then
                m%res%criterion = 'linesearch alpha is zero'
                return
            end if
            m%res%criterion = criterion(eng, m, iter, e_old, eng%pe)
            if (len(m%res%criterion) > 0) return
            n = eng%atoms%nlocal
            s = [sum(eng%atoms%f(:, 1:n)**2), sum(eng%atoms%f(:, 1:n)*r%g), sum(r%g**2)]
            call sum_all(s)
            beta = 0
            if (s(3) > 0) beta = max(0.0_dp, (s(1) - s(2))/s(3))
            if (mod(iter, max(1_i8, 3*eng%natoms)) == 0) beta = 0
            r%h = eng%atoms%f(:, 1:n) + beta*r%h
            r%g = eng%atoms%f(:, 1:n)
            hf = sum(r%h*r%g)
            call sum_all(hf)
            if (hf <= 0) r%h = r%g
        end do
    end subroutine cg

    !> Along h from the present positions: see the module header. ok = .false.: no step lowered
    !> the energy (the positions and forces are those of the start again).
    subroutine line_search(eng, p, r, ok)
        type(engine_t), intent(inout) :: eng
        type(minimize_params_t), intent(in) :: p
        type(cg_rows_t), intent(inout) :: r
        logical, intent(out) :: ok
        real(dp) :: e0, fh0, fh1, hmax, alpha, alpha_q, tol
        integer :: n, k, i
        n = eng%atoms%nlocal
        do i = 1, n
            r%x0(:, i) = eng%atoms%x(:, i) + eng%atoms%image(:, i)*eng%box%length
        end do
        e0 = eng%pe
        fh0 = directional(eng, r%h)
        hmax = 0
        if (n > 0) hmax = maxval(abs(r%h))
        call max_all(hmax)
        ok = .false.
        if (fh0 <= 0 .or. hmax <= 0) return
        tol = 1.0e-14_dp*max(abs(e0), 1.0_dp)
        alpha = min(1.0_dp, p%dmax/hmax)
        do k = 1, 60
            call move_to(eng, r, alpha)
            fh1 = directional(eng, r%h)
            if (fh1 >= 0 .and. eng%pe <= e0 + tol) then
                ok = .true.              ! still going down at alpha: take it
                return
            end if
            ! past the minimum along h (or the energy rose): the secant on the derivative
            alpha_q = alpha*fh0/(fh0 - fh1)
            if (alpha_q > 0 .and. alpha_q < alpha) then
                call move_to(eng, r, alpha_q)
                if (eng%pe <= e0 + tol) then
                    ok = .true.
                    return
                end if
            end if
            alpha = 0.5_dp*alpha
        end do
        call move_to(eng, r, 0.0_dp)
    end subroutine line_search

    !> x = x0 + alpha h (unwrapped; the present image flags taken off) for the owned atoms, then
    !> forces: ghosts refreshed, or the list rebuilt when an atom has moved skin/2 (the rows
    !> remapped to the atoms' new order).
    subroutine move_to(eng, r, alpha)
        type(engine_t), intent(inout) :: eng
        type(cg_rows_t), intent(inout) :: r
        real(dp), intent(in) :: alpha
        integer :: i
        do i = 1, eng%atoms%nlocal
            eng%atoms%x(:, i) = r%x0(:, i) + alpha*r%h(:, i) - eng%atoms%image(:, i)*eng%box%length
        end do
        if (eng%plan%pair_mode /= pair_all .and. eng%list%needs_rebuild(eng%atoms)) then
            call eng%rebuild()
            call remap(eng, r)
        else
            call eng%refresh_ghosts()
        end if
        call eng%compute_forces(.true.)
    end subroutine move_to

    real(dp) function directional(eng, h) result(fh)
        type(engine_t), intent(inout) :: eng
        real(dp), intent(in) :: h(:, :)
        fh = sum(eng%atoms%f(:, 1:eng%atoms%nlocal)*h)
        call sum_all(fh)
    end function directional

    !> The rows of r in the owned atoms' present order (after a rebuild). Every rank gathers every
    !> rank's rows (ids and nine numbers each) and takes its atoms' rows by id. Collective.
    subroutine remap(eng, r)
        type(engine_t), intent(inout) :: eng
        type(cg_rows_t), intent(inout) :: r
        real(dp), allocatable :: rows(:, :), all_rows(:, :)
        integer(i8), allocatable :: all_id(:)
        integer, allocatable :: where(:)
        integer :: i, n
        allocate (rows(9, size(r%id)))
        rows(1:3, :) = r%x0; rows(4:6, :) = r%h; rows(7:9, :) = r%g
        call gather_rows(r%id, rows, all_id, all_rows)
        allocate (where(maxval([0_i8, all_id])))
        where = 0
        do i = 1, size(all_id)
            where(all_id(i)) = i
        end do
        n = eng%atoms%nlocal
        r%id = eng%atoms%id(1:n)
        deallocate (r%x0, r%h, r%g)
        allocate (r%x0(3, n), r%h(3, n), r%g(3, n))
        do i = 1, n
            r%x0(:, i) = all_rows(1:3, where(r%id(i)))
            r%h(:, i) = all_rows(4:6, where(r%id(i)))
            r%g(:, i) = all_rows(7:9, where(r%id(i)))
        end do
    end subroutine remap

    !> Every rank's ids and rows (m numbers per atom), concatenated in rank order. Collective.
    subroutine gather_rows(id, rows, all_id, all_rows)
        use mpi_f08, only: MPI_Allgatherv, MPI_INTEGER8, MPI_DOUBLE_PRECISION
        integer(i8), intent(in) :: id(:)
        real(dp), intent(in) :: rows(:, :)
        integer(i8), allocatable, intent(out) :: all_id(:)
        real(dp), allocatable, intent(out) :: all_rows(:, :)
        integer, allocatable :: counts(:), displs(:)
        integer :: n, m
        n = size(id); m = size(rows, 1)
        allocate (counts(world%nprocs), displs(world%nprocs))
        call gather_counts(n, counts, displs)
        allocate (all_id(sum(counts)), all_rows(m, sum(counts)))
        call MPI_Allgatherv(id, n, MPI_INTEGER8, all_id, counts, displs, MPI_INTEGER8, world%comm)
        call MPI_Allgatherv(rows, m*n, MPI_DOUBLE_PRECISION, all_rows, m*counts, m*displs, MPI_DOUBLE_PRECISION, &
                            world%comm)
    end subroutine gather_rows

    subroutine fire(eng, m)
        type(engine_t), intent(inout) :: eng
        type(minimization_t), intent(inout) :: m
        real(dp), parameter :: finc = 1.1_dp, fdec = 0.5_dp, alpha0 = 0.1_dp, falpha = 0.99_dp
        integer, parameter :: nmin = 5
        real(dp), allocatable :: v_saved(:, :)
        integer(i8), allocatable :: id_saved(:)
        real(dp) :: dt, dtmax, alpha, pw, s(3), vmax, e_old, scale, dtf
        integer(i8) :: iter
        integer :: n, npos, i
        n = eng%atoms%nlocal
        allocate (v_saved(3, n))
        v_saved = eng%atoms%v(:, 1:n)
        id_saved = eng%atoms%id(1:n)
        eng%atoms%v(:, 1:n) = 0
        dt = m%p%dt; dtmax = 10*m%p%dt; alpha = alpha0; npos = 0
        iter = 0
        do
            iter = iter + 1
            e_old = eng%pe
            n = eng%atoms%nlocal
            s = [sum(eng%atoms%f(:, 1:n)*eng%atoms%v(:, 1:n)), sum(eng%atoms%v(:, 1:n)**2), &
                 sum(eng%atoms%f(:, 1:n)**2)]
            call sum_all(s)
            pw = s(1)
            if (pw > 0) then
                npos = npos + 1
                if (npos > nmin) then
                    dt = min(dt*finc, dtmax)
                    alpha = alpha*falpha
                end if
            else
                npos = 0
                dt = dt*fdec
                alpha = alpha0
                if (iter > 1) eng%atoms%x(:, 1:n) = eng%atoms%x(:, 1:n) - 0.5_dp*dt*eng%atoms%v(:, 1:n)
                eng%atoms%v(:, 1:n) = 0
            end if
            ! semi-implicit Euler: v += dt f / m, mixed towards f, then x += dt v
            dtf = dt*eng%units%ftm2v
            do i = 1, n
                eng%atoms%v(:, i) = eng%atoms%v(:, i) + dtf/mass_of(eng, i)*eng%atoms%f(:, i)
            end do
            s(1:2) = [sum(eng%atoms%v(:, 1:n)**2), sum(eng%atoms%f(:, 1:n)**2)]
            call sum_all(s(1:2))
            if (s(2) > 0) eng%atoms%v(:, 1:n) = (1 - alpha)*eng%atoms%v(:, 1:n) + &
                                               alpha*sqrt(s(1)/s(2))*eng%atoms%f(:, 1:n)
            vmax = 0
            if (n > 0) vmax = maxval(abs(eng%atoms%v(:, 1:n)))
            call max_all(vmax)
            scale = 1
            if (vmax*dt > m%p%dmax) scale = m%p%dmax/(vmax*dt)
            eng%atoms%x(:, 1:n) = eng%atoms%x(:, 1:n) + scale*dt*eng%atoms%v(:, 1:n)
            call evaluate(eng, iter)
            call write_row(eng, iter, m%unit)
            m%res%iterations = iter
            m%res%criterion = criterion(eng, m, iter, e_old, eng%pe)
            if (len(m%res%criterion) > 0) exit
        end do
        call restore_velocities(eng, id_saved, v_saved)
    end subroutine fire

    !> The velocities saved before FIRE, put back by atom id (a rebuild may have reordered or
    !> migrated atoms: each rank finds its atoms' rows among all ranks' saved rows).
    subroutine restore_velocities(eng, ids, v)
        type(engine_t), intent(inout) :: eng
        integer(i8), intent(in) :: ids(:)
        real(dp), intent(in) :: v(:, :)
        real(dp), allocatable :: vall(:, :)
        integer(i8), allocatable :: idall(:)
        integer(i8), allocatable :: row(:)
        integer :: i, k
        call gather_rows(ids, v, idall, vall)
        allocate (row(maxval([0_i8, idall])))
        row = 0
        do k = 1, size(idall)
            row(idall(k)) = k
        end do
        do i = 1, eng%atoms%nlocal
            eng%atoms%v(:, i) = vall(:, row(eng%atoms%id(i)))
        end do
    end subroutine restore_velocities

    real(dp) function mass_of(eng, i) result(m)
        type(engine_t), intent(in) :: eng
        integer, intent(in) :: i
        if (eng%atoms%per_atom_mass) then
            m = eng%atoms%rmass(i)
        else
            m = eng%atoms%mass(eng%atoms%type(i))
        end if
    end function mass_of

    real(dp) function dot_ff(eng) result(ff)
        type(engine_t), intent(inout) :: eng
        ff = sum(eng%atoms%f(:, 1:eng%atoms%nlocal)**2)
        call sum_all(ff)
    end function dot_ff

    real(dp) function fmax_all(eng) result(fm)
        type(engine_t), intent(inout) :: eng
        fm = 0
        if (eng%atoms%nlocal > 0) fm = maxval(abs(eng%atoms%f(:, 1:eng%atoms%nlocal)))
        call max_all(fm)
    end function fmax_all

    !> One thermo row: iteration, energy, largest force component, force 2-norm. Collective.
    subroutine write_row(eng, iter, unit)
        type(engine_t), intent(inout) :: eng
        integer(i8), intent(in) :: iter
        integer, intent(in) :: unit
        real(dp) :: fm, fn
        fm = fmax_all(eng)
        fn = sqrt(dot_ff(eng))
        if (unit /= no_unit .and. world%rank == 0) write (unit, '(i0,3(",",es24.16))') iter, eng%pe, fm, fn
    end subroutine write_row

end module terrace_minimize
