!> The engine state shared by every integrator: box, atoms, domain, neighbour list, potential,
!> scene plan and timers, and the operations the integrators are written in: rebuild (migrate,
!> sort, halo, list), refresh ghosts, force evaluation (with reverse sums), ray pass, drift, thermo
!> sample. It receives a built scene (terrace_scene_builder) and knows no potential by name: the
!> potential is a class(potential_t), and the halo operations a many-body potential needs between
!> its passes are this module's engine_halo_t.
module terrace_engine
    use terrace_kinds, only: dp, i8
    use terrace_units, only: units_t
    use terrace_box, only: box_t
    use terrace_atoms, only: atoms_t
    use terrace_vec3, only: add_scaled, fill_zero
    use terrace_velocities, only: kinetic_energy, atom_mass
    use terrace_thermostat, only: thermostat_dof
    use terrace_domain, only: domain_t
    use terrace_replicate, only: replicate_t
    use terrace_neighbor_list, only: neighbor_list_t
    use terrace_potential, only: potential_t, halo_ops_t, max_warning_flags, virial_diagonal
    use terrace_timers, only: timers_t, t_pair, t_neigh, t_comm, t_search
    use terrace_observables, only: thermo_sample_t
    use terrace_scene_plan, only: plan_t, pair_all, pair_cells, pair_none
    use terrace_scene, only: scene_t
    use terrace_overlap_check, only: check_overlaps
    use terrace_mpi_env, only: world, sum_all, any_all
    use terrace_errors, only: stop_all, check_all, warn
    use terrace_named_values, only: named_values_t
    implicit none
    private

    !> What the engine is made from besides the scene (the run's units applied).
    type, public :: engine_params_t
        type(units_t) :: units
        integer :: dimension = 3
        real(dp) :: skin = 0                     !< the neighbour list's skin
        !> > 0 (velocity Verlet, with a scene plan's inner_list): the built list's skin; the force
        !> pass reads the pairs within cutoff + skin pruned from it (engine_list_due)
        real(dp) :: outer_skin = 0
        !> > 0 (with outer_skin and a fixed list schedule): prune every this many steps instead
        integer :: prune_every = 0
        integer :: list_every = 1                !< build the list at most every this many steps
        logical :: list_check = .true.           !< and only when an atom has moved skin/2
        logical :: straight_lines = .false.      !< the integrator moves atoms on rays (energy stepping)
        logical :: virial_diagonal = .false.     !< force passes with energy also give the virial's diagonal
    end type engine_params_t

    !> Everything a trial move of the box (or of the atoms) changes, for an exact return to the
    !> state before it: the atoms (positions, velocities, forces, order, ghosts), the lists, the
    !> domain's brick and halo, the box and the last energy and virial. The engine extends it:
    !> save_state and restore_state copy this part of the engine.
    type, public :: engine_state_t
        type(box_t) :: box
        type(atoms_t) :: atoms
        type(domain_t) :: dom
        type(neighbor_list_t) :: list
        !> Energy stepping with a pair potential: the pairs of `list` within rc + skin/4, pruned
        !> again whenever an atom has moved skin/8 (events are short: many per prune), and used
        !> by the force and ray passes instead of `list` (a quarter of its pairs lie beyond that).
        type(neighbor_list_t) :: inner
        !> use_inner: no atom had moved more than (skin - skin of the pruned list)/2 from the build
        !> at the last prune, so the built list cannot expire before the pruned one (its expiry is
        !> not computed until the next prune)
        logical :: built_covered = .false.
        real(dp) :: pe = 0, virial = 0          !< global, from the last energy evaluation
        !> virial_diag = (W_xx, W_yy, W_zz), global, when want_virial_diag (an anisotropic barostat
        !> asks for it)
        real(dp) :: virial_diag(3) = 0
        !> The lists have wrapped images (list%wrapped, set at each build: set_wrapped_images) and the
        !> ghosts' positions were not refreshed since the owners moved: whatever reads them (a prune)
        !> refreshes them first (fresh_ghosts)
        logical :: ghosts_stale = .false.
    end type engine_state_t

    type, public, extends(engine_state_t) :: engine_t
        type(units_t) :: units
        integer :: dimension = 3
        !> degrees of freedom of the temperature: d N - d unless a thermostat sets its own
        real(dp) :: ndof = 0
        type(replicate_t) :: rep
        logical :: use_inner = .false.
        !> outer_list: velocity Verlet's list is built with &neighbor outer_skin and `inner` (pairs within
        !> rc + skin) pruned from it (engine_list_due decides); otherwise energy stepping's inner list
        logical :: outer_list = .false.
        real(dp) :: inner_skin = 0               !< the pruned list's skin (inner_cut = cutmax + inner_skin)
        integer :: prune_every = 0               !< outer_list on a fixed schedule: steps between prunes
        integer :: prunes = 0
        class(potential_t), allocatable :: pot
        real(dp) :: cutmax = 0                   !< the potential's largest cutoff (0: none)
        type(plan_t) :: plan
        type(timers_t) :: timers
        integer(i8) :: natoms = 0
        !> want_virial_diag: the force passes with energy also give the virial's diagonal
        logical :: want_virial_diag = .false.
        integer(i8) :: force_evaluations = 0
        character(len=:), allocatable :: source  !< where the atoms came from (for messages)
        logical :: restarted = .false.           !< started from &system read_checkpoint
        logical :: validity_checks = .false.     !< the potential can reach states without finite energy
        type(named_values_t) :: restart_values    !< the checkpoint's named values (integrator state)
        integer(i8), allocatable :: mesh_tet(:, :) !< a mesh scene: (4, ntet) node ids (trajectory, XDMF)
        integer(i8) :: mesh_hash = 0             !< a mesh scene: its fingerprint (checkpoints)
    contains
        procedure :: setup => engine_setup
        procedure :: rebuild => engine_rebuild
        procedure :: refresh_ghosts => engine_refresh_ghosts
        procedure :: compute_forces => engine_compute_forces
        procedure :: sample => engine_sample
        procedure :: dof => engine_dof
        procedure :: ray_pass => engine_ray_pass
        procedure :: drift => engine_drift
        procedure :: sync_ghosts => engine_sync_ghosts
        procedure :: list_expiry => engine_list_expiry
        procedure :: prune => engine_prune
        procedure :: list_due => engine_list_due
        procedure :: report_warnings => engine_report_warnings
        procedure :: check_valid => engine_check_valid
        procedure :: scale_box => engine_scale_box
        procedure :: save_state => engine_save_state
        procedure :: restore_state => engine_restore_state
    end type engine_t

    !> What engine_list_due asks for after a drift: nothing (the ghosts refreshed), a prune of the
    !> inner list from the built one, or a rebuild.
    integer, parameter, public :: list_keep = 0, list_prune = 1, list_rebuild = 2

    !> The halo operations handed to the potential during a force pass.
    type, extends(halo_ops_t) :: engine_halo_t
        type(engine_t), pointer :: eng => null()
    contains
        procedure :: reverse_sum => halo_reverse_sum
        procedure :: forward => halo_forward
    end type engine_halo_t

contains

    !> Take over a built scene, build the halo and the neighbour list, check for overlapping atoms
    !> and compute the first forces (a restart takes the interrupted run's). Collective.
    subroutine engine_setup(self, p, scene)
        class(engine_t), intent(inout) :: self
        type(engine_params_t), intent(in) :: p
        type(scene_t), intent(inout) :: scene
        integer :: i
        self%units = p%units
        self%dimension = p%dimension
        self%want_virial_diag = p%virial_diagonal
        self%box = scene%box
        self%atoms = scene%atoms
        self%dom = scene%dom
        call move_alloc(scene%pot, self%pot)
        self%plan = scene%plan
        self%natoms = scene%natoms
        self%ndof = thermostat_dof(.true., .false., p%dimension, scene%natoms)
        self%cutmax = scene%cutmax
        self%source = scene%source
        self%restarted = scene%restarted
        if (allocated(scene%mesh_tet)) call move_alloc(scene%mesh_tet, self%mesh_tet)
        self%mesh_hash = scene%mesh_hash
        self%list%dimension = p%dimension
        self%list%all_pairs = self%plan%pair_mode == pair_all
        self%use_inner = self%plan%inner_list
        self%outer_list = self%use_inner .and. p%outer_skin > 0
        if (self%outer_list) then
            self%inner_skin = p%skin
            self%prune_every = p%prune_every
            call self%list%init(self%cutmax, p%outer_skin, p%dimension)
        else
            self%inner_skin = 0.25_dp*p%skin
            if (self%plan%pair_mode == pair_cells) call self%list%init(self%cutmax, p%skin, p%dimension)
        end if
        self%list%every = p%list_every
        self%list%check = p%list_check
        ! no pair list: bins (for the spatial sort) sized by the halo, and the displacement reference
        if (self%plan%pair_mode == pair_none) call self%list%init(self%pot%halo_reach(), p%skin, p%dimension)
        self%validity_checks = self%pot%may_become_invalid()
        ! ray passes of some many-body terms (and the force pass of node-to-face contact) need each
        ! owned atom's whole neighbourhood
        self%list%want_below = self%pot%needs_full_neighbourhood(p%straight_lines)
        self%list%want_types = self%pot%wants_neighbour_types()
        self%list%type_order = self%pot%neighbour_type_order()
        self%list%want_clusters = self%plan%cluster_pairs      ! (the plan sets it with cell lists only)
        ! a potential whose passes read the half list and nothing else never reads a ghost below the
        ! brick along z (domain_t%ghosts_below)
        self%dom%ghosts_below = .not. (self%plan%pair_mode == pair_cells .and. p%dimension == 3 .and. &
                                       self%pot%runs_on_pruned_list() .and. .not. self%list%want_below .and. &
                                       .not. self%list%want_clusters)
        self%dom%half_images = self%plan%half_images .and. .not. self%dom%ghosts_below
        call self%rebuild()
        call check_overlaps(self%atoms, self%list, self%pot, self%plan%pair_mode, self%source)
        call self%compute_forces(.true.)
        if (self%restarted) then
            do i = 1, self%atoms%nlocal
                self%atoms%f(:, i) = scene%restart_f(:, self%atoms%id(i))
            end do
            self%restart_values = scene%restart_values
        end if
    end subroutine engine_setup

    !> Degrees of freedom for the temperature: d N - d (as LAMMPS), or d N under a thermostat that
    !> also drives the total momentum (Langevin, Andersen without zero_momentum): the thermostat's dof, which the run sets.
    pure real(dp) function engine_dof(self)
        class(engine_t), intent(in) :: self
        engine_dof = self%ndof
    end function engine_dof

    !> Migrate atoms, sort them spatially, rebuild the halo and the neighbour list.
    subroutine engine_rebuild(self)
        class(engine_t), intent(inout) :: self
        real(dp) :: lo(3), hi(3)
        integer :: d, n
        if (self%plan%pair_mode == pair_all) then
            call self%timers%start(t_comm)
            if (world%nprocs > 1) call self%rep%setup(self%atoms)
            call self%timers%stop(t_comm)
            call self%atoms%refresh_rmass()
            call self%pot%on_rebuild(self%atoms)
            return
        end if
        call self%timers%start(t_comm)
        call self%dom%migrate(self%atoms)
        call self%timers%stop(t_comm)
        call self%timers%start(t_neigh)
        n = self%atoms%nlocal
        lo = self%dom%sublo; hi = self%dom%subhi
        do d = 1, self%box%dimension
            if (n > 0) then
                lo(d) = min(lo(d), minval(self%atoms%x(d, 1:n)))
                hi(d) = max(hi(d), maxval(self%atoms%x(d, 1:n)))
            end if
        end do
        lo = lo - self%dom%cutghost; hi = hi + self%dom%cutghost
        ! (no ghost below the brick along z: no bins there)
        if (.not. self%dom%ghosts_below) lo(3) = lo(3) + self%dom%cutghost
        call self%list%setup_bins(lo, hi, n)
        call self%list%sort_owned(self%atoms)
        call self%timers%stop(t_neigh)
        call self%timers%start(t_comm)
        call self%dom%borders(self%atoms)
        call self%timers%stop(t_comm)
        call self%timers%start(t_neigh)
        if (self%plan%pair_mode == pair_cells) then
            self%list%half_images = self%dom%halved
            call self%list%build(self%atoms)
            call set_wrapped_images(self)
            if (self%use_inner) call self%inner%prune(self%list, self%atoms, inner_cut(self))
            self%built_covered = self%use_inner
        else
            call self%list%hold(self%atoms)           ! no pair list: only the displacement reference
        end if
        call self%atoms%refresh_rmass()
        call self%pot%on_rebuild(self%atoms)
        call self%timers%stop(t_neigh)
    end subroutine engine_rebuild

    !> After a build: the lists have wrapped images (neighbor_list_t%wrapped; the force pass reads each
    !> ghost as its owner at the nearest image, so that the ghosts need no refresh between builds and
    !> their forces no reverse sum) where the plan allows them (plan%wrap_images), every ghost is a
    !> periodic image of an owned atom (one rank) and the box is still more than twice the list's
    !> cutoff in every dimension (a margin of 1e-9 for round-off); the built list's rows then also as
    !> byte offsets of the owners' records (the fixed-point prune's and the mixed pass's).
    subroutine set_wrapped_images(self)
        class(engine_t), intent(inout) :: self
        logical :: ok
        ok = self%plan%wrap_images .and. .not. (self%want_virial_diag .or. self%list%want_below .or. &
                                                self%list%want_clusters)
        if (ok) ok = all(self%box%periodic) .and. 2*self%list%cut < (1 - 1.0e-9_dp)*minval(self%box%length)
        if (ok) ok = self%dom%image_owners(self%atoms, self%list%image_of)
        self%list%wrapped = ok
        self%inner%wrapped = ok .and. self%use_inner
        if (ok) then
            self%list%wrap_box = [self%box%lo, self%box%length]
            self%inner%wrap_box = self%list%wrap_box
            call self%list%wrap_offsets(self%atoms%nlocal)   ! (a pruned list forms its own from these)
        end if
        self%ghosts_stale = .false.
    end subroutine set_wrapped_images

    !> The ghosts' positions from their owners now if they were left stale (wrapped images).
    subroutine fresh_ghosts(self)
        class(engine_t), intent(inout) :: self
        if (.not. self%ghosts_stale) return
        call self%timers%start(t_comm)
        call self%dom%forward(self%atoms%x, .true.)
        call self%timers%stop(t_comm)
        self%ghosts_stale = .false.
    end subroutine fresh_ghosts

    !> Bring ghost positions up to date (no rebuild); with wrapped images only marked stale (the
    !> force pass does not read them; a prune refreshes them).
    subroutine engine_refresh_ghosts(self)
        class(engine_t), intent(inout) :: self
        call ghosts_from_owners(self, velocities=.false.)
    end subroutine engine_refresh_ghosts

    !> Forces on owned atoms (ghost contributions summed back); with want_energy also the global
    !> potential energy and virial, and with want_virial_diag the virial's diagonal (from the rows'
    !> x_a f_a before the reverse sum: terrace_potential's virial_diagonal). Halo calls made by the
    !> potential between its passes are timed as communication.
    subroutine engine_compute_forces(self, want_energy, partial)
        class(engine_t), intent(inout), target :: self
        logical, intent(in) :: want_energy
        !> .true.: pe and virial are left as this rank's parts where the potential does not sum them
        !> over ranks itself (the caller sums them with its own sums: one reduction instead of two;
        !> virial_diag, when wanted, is summed here all the same)
        logical, intent(in), optional :: partial
        real(dp) :: ew(5)
        integer :: nall
        logical :: sum_here, diag, wrapped
        type(engine_halo_t) :: halo
        halo%eng => self
        call self%timers%start(t_pair)
        ! wrapped images: the pass leaves the ghosts' forces alone (no reverse sum) and reads the box
        wrapped = self%list%wrapped
        if (wrapped) then
            self%list%wrap_box = [self%box%lo, self%box%length]
            self%inner%wrap_box = self%list%wrap_box
            nall = self%atoms%nlocal
        else
            nall = self%atoms%nall()
        end if
        call fill_zero(3*nall, self%atoms%f)
        if (self%use_inner) then
            call self%pot%forces(self%atoms, self%inner, halo, want_energy, ew(1), ew(2))
        else
            call self%pot%forces(self%atoms, self%list, halo, want_energy, ew(1), ew(2))
        end if
        diag = want_energy .and. self%want_virial_diag
        if (diag) ew(3:5) = virial_diagonal(self%atoms%x, self%atoms%f, nall)
        call self%timers%stop(t_pair)
        if (self%validity_checks) call check_list_problem(self)
        if (self%plan%pair_mode /= pair_all .and. .not. wrapped) then
            call self%timers%start(t_comm)
            call self%dom%reverse(self%atoms%f)
            call self%timers%stop(t_comm)
        end if
        sum_here = .not. self%pot%sums_global()
        if (present(partial)) sum_here = sum_here .and. .not. partial
        if (want_energy) then
            if (world%nprocs > 1 .and. (sum_here .or. diag)) then
                call self%timers%start(t_comm)
                if (sum_here .and. diag) then
                    call sum_all(ew)
                else if (sum_here) then
                    call sum_all(ew(1:2))
                else
                    call sum_all(ew(3:5))
                end if
                call self%timers%stop(t_comm)
            end if
            self%pe = ew(1); self%virial = ew(2)
            if (diag) self%virial_diag = ew(3:5)
        end if
        self%force_evaluations = self%force_evaluations + 1
    end subroutine engine_compute_forces

    !> Ghost rows summed into their owners (the potential's pass is paused on the timers).
    subroutine halo_reverse_sum(self, buf)
        class(engine_halo_t), intent(inout) :: self
        real(dp), intent(inout) :: buf(:, :)
        call self%eng%timers%stop(t_pair)
        call self%eng%timers%start(t_comm)
        if (self%eng%plan%pair_mode == pair_all) call stop_all('internal: a halo sum was asked on the all-pairs path')
        call self%eng%dom%reverse(buf)
        call self%eng%timers%stop(t_comm)
        call self%eng%timers%start(t_pair)
    end subroutine halo_reverse_sum

    !> Owners' rows copied to their ghosts.
    subroutine halo_forward(self, buf)
        class(engine_halo_t), intent(inout) :: self
        real(dp), intent(inout) :: buf(:, :)
        call self%eng%timers%stop(t_pair)
        call self%eng%timers%start(t_comm)
        if (self%eng%plan%pair_mode == pair_all) then
            if (world%nprocs > 1) call self%eng%rep%gather(self%eng%atoms, buf)
        else
            call self%eng%dom%forward(buf, .false.)
        end if
        call self%eng%timers%stop(t_comm)
        call self%eng%timers%start(t_pair)
    end subroutine halo_forward

    !> Thermo quantities from the current velocities and the last energy evaluation.
    function engine_sample(self, step, time) result(s)
        class(engine_t), intent(inout) :: self
        integer(i8), intent(in) :: step
        real(dp), intent(in) :: time
        type(thermo_sample_t) :: s
        real(dp) :: dof, pl(6), m, r(3)
        integer :: i
        s%step = step; s%time = time
        s%ke = kinetic_energy(self%atoms, self%units)
        pl = 0
        do i = 1, self%atoms%nlocal
            m = atom_mass(self%atoms, i)
            r = self%atoms%x(:, i) + self%atoms%image(:, i)*self%box%length
            pl(1:3) = pl(1:3) + m*self%atoms%v(:, i)
            pl(4:6) = pl(4:6) + m*[r(2)*self%atoms%v(3, i) - r(3)*self%atoms%v(2, i), &
                                   r(3)*self%atoms%v(1, i) - r(1)*self%atoms%v(3, i), &
                                   r(1)*self%atoms%v(2, i) - r(2)*self%atoms%v(1, i)]
        end do
        call sum_all(pl)
        s%momentum = pl(1:3); s%angular = pl(4:6)
        s%pe = self%pe
        s%etotal = s%ke + s%pe
        dof = self%dof()
        s%temp = 0
        if (dof > 0) s%temp = 2*s%ke/(dof*self%units%boltz)
        s%press = (2*s%ke + self%virial)/(self%box%dimension*self%box%volume())*self%units%nktv2p
    end function engine_sample

    !> Energy, its first two derivatives along the ray x + s v, and the virial, summed over all
    !> ranks: out = (V, dV/ds, d2V/ds2, W). One pass over the pairs, one global sum (none on one rank).
    !> The caller times its whole search as Search (two clock reads per search, not per pass: a
    !> small cluster makes a million searches a second); the global sum is taken out of it as Comm.
    subroutine engine_ray_pass(self, s, out)
        class(engine_t), intent(inout) :: self
        real(dp), intent(in) :: s
        real(dp), intent(out) :: out(4)
        call fresh_ghosts(self)
        if (self%use_inner) then
            call self%pot%ray(self%atoms, self%inner, s, out)
        else
            call self%pot%ray(self%atoms, self%list, s, out)
        end if
        ! (nothing to sum on one rank: no call, no timer)
        if (world%nprocs == 1 .or. self%pot%sums_global()) return
        call self%timers%stop(t_search)
        call self%timers%start(t_comm)
        call sum_all(out)
        call self%timers%stop(t_comm)
        call self%timers%start(t_search)
    end subroutine engine_ray_pass

    !> Straight-line motion of every atom, owned and ghost: x += s v.
    subroutine engine_drift(self, s)
        class(engine_t), intent(inout) :: self
        real(dp), intent(in) :: s
        integer :: n
        n = self%atoms%nall()
        call add_scaled(3*n, s, self%atoms%v, self%atoms%x)
    end subroutine engine_drift

    !> Ghost positions and velocities from their owners (after a velocity jump).
    subroutine engine_sync_ghosts(self)
        class(engine_t), intent(inout) :: self
        call ghosts_from_owners(self, velocities=.true.)
    end subroutine engine_sync_ghosts

    subroutine ghosts_from_owners(self, velocities)
        class(engine_t), intent(inout) :: self
        logical, intent(in) :: velocities
        ! all pairs on one rank: no ghosts (no call, no timer)
        if (self%plan%pair_mode == pair_all .and. world%nprocs == 1) return
        ! wrapped images: positions only marked stale (velocities: refreshed, with the positions)
        self%ghosts_stale = self%list%wrapped .and. .not. velocities
        if (self%ghosts_stale) return
        call self%timers%start(t_comm)
        if (self%plan%pair_mode == pair_all) then
            if (world%nprocs > 1) call self%rep%gather(self%atoms, self%atoms%x)
            if (world%nprocs > 1 .and. velocities) call self%rep%gather(self%atoms, self%atoms%v)
        else
            if (velocities) then
                call self%dom%forward_xv(self%atoms%x, self%atoms%v)
            else
                call self%dom%forward(self%atoms%x, .true.)
            end if
        end if
        call self%timers%stop(t_comm)
    end subroutine ghosts_from_owners

    !> Earliest time (from now, this rank's atoms) at which the neighbour list expires (an owned
    !> atom moving in a straight line reaches skin/2 from where the list was built), or the pruned
    !> list (use_inner) does. Huge when there is no list. While built_covered the built list is not
    !> looked at (built = huge: it outlives the pruned one).
    real(dp) function engine_list_expiry(self, built) result(t)
        class(engine_t), intent(in) :: self
        real(dp), intent(out), optional :: built   !< the built list's own expiry (t: also the pruned one's)
        t = huge(1.0_dp)
        if (self%plan%pair_mode /= pair_all .and. .not. self%built_covered) t = self%list%expiry(self%atoms)
        if (present(built)) built = t
        if (self%use_inner) t = min(t, self%inner%expiry(self%atoms))
    end function engine_list_expiry

    !> The pruned list again from the built one (use_inner), at the present positions.
    subroutine engine_prune(self)
        class(engine_t), intent(inout) :: self
        if (.not. self%use_inner) return
        if (self%inner%prune_reads_ghosts(self%list)) call fresh_ghosts(self)
        call self%timers%start(t_neigh)
        call self%inner%prune(self%list, self%atoms, inner_cut(self))
        ! an atom within (skin - inner skin)/2 of its place at the build stays within skin/2 of it
        ! until it has moved the pruned list's skin/2 (the triangle inequality): the built list then
        ! outlives the pruned one (a margin of 1e-9 of the skin for round-off). Only the expiry of an
        ! exact list reads it, not prune_every's fixed schedule.
        if (self%prune_every == 0) self%built_covered = .not. self%list%moved_beyond(self%atoms, &
                                 0.5_dp*(self%list%skin - self%inner%skin) - 1.0e-9_dp*self%list%skin)
        self%prunes = self%prunes + 1
        call self%timers%stop(t_neigh)
    end subroutine engine_prune

    !> The pruned list's cutoff: rc + skin/4 with energy stepping (its skin/2 is then skin/8), rc + skin
    !> with velocity Verlet's outer list (the built list's skin is then outer_skin).
    pure real(dp) function inner_cut(self)
        class(engine_t), intent(in) :: self
        inner_cut = self%cutmax + self%inner_skin
    end function inner_cut

    !> After a drift (velocity Verlet): keep the lists, prune the inner one again or rebuild; collective,
    !> the same answer on every rank (the displacement maxima are global). forced: a rebuild the caller
    !> needs anyway (a checkpoint). Without the outer list: a rebuild when the list's schedule says so.
    !> With it (built list: skin S = outer_skin at the last build; inner list: skin s = &neighbor skin at
    !> the last prune; D_b, D_p an atom's displacement since the build and since the prune):
    !> - the inner list holds every pair within rc while every D_p <= s/2: such a pair was within
    !>   rc + s at the prune (triangle inequality), and the prune kept every pair of the built list
    !>   that was within rc + s then, so the pair was kept if the built list held it;
    !> - the built list holds every pair within rc + s at the prune if every D_b <= (S - s)/2 then: such
    !>   a pair was within rc + s + (S - s) = rc + S at the build;
    !> so: nothing while every D_p <= s/2 (the check of a list of skin s without the outer one); when
    !> an atom has moved further, a prune if every D_b <= (S - s)/2 (less 1e-9 S for round-off), and
    !> otherwise a rebuild (which prunes at once).
    !> With prune_every (a fixed schedule, &neighbor buffer_tolerance or every and check = .false.): a
    !> rebuild when the list's schedule says so, otherwise a prune at the multiples of prune_every
    !> (not exact: pairs may be missed, as with the fixed schedule's built list).
    integer function engine_list_due(self, step, forced) result(due)
        class(engine_t), intent(inout) :: self
        integer(i8), intent(in) :: step
        logical, intent(in) :: forced
        logical :: far
        if (.not. self%outer_list) then
            due = merge(list_rebuild, list_keep, self%list%rebuild_due(self%atoms, step, forced))
            return
        end if
        due = list_rebuild
        if (forced) return
        if (self%prune_every > 0) then
            due = list_keep
            if (mod(step, int(self%prune_every, i8)) == 0) due = list_prune
            if (self%list%rebuild_due(self%atoms, step, .false.)) due = list_rebuild
            return
        end if
        due = list_keep
        if (.not. self%inner%needs_rebuild(self%atoms)) return
        far = self%list%moved_beyond(self%atoms, &
                                     0.5_dp*(self%list%skin - self%inner%skin) - 1.0e-9_dp*self%list%skin)
        call any_all(far)
        due = merge(list_rebuild, list_prune, far)
    end function engine_list_due

    !> Warnings gathered during the run, printed once by rank 0 (collective).
    subroutine engine_report_warnings(self)
        class(engine_t), intent(inout) :: self
        logical :: flags(max_warning_flags)
        character(len=512) :: text
        integer :: k
        flags = self%pot%warning_flags()
        do k = 1, max_warning_flags
            call any_all(flags(k))
        end do
        if (self%pot%warning(flags, text) .and. world%rank == 0) call warn(trim(text))
    end subroutine engine_report_warnings

    !> Stop every rank with the potential's description when any rank's state is invalid (after a
    !> force pass of an integrator with fixed steps). Collective.
    !> A pass that could not serve the state from its list (potential%list_problem) stops every rank
    !> with the failing rank's description. Collective.
    subroutine check_list_problem(self)
        class(engine_t), intent(inout) :: self
        character(len=512) :: text
        logical :: bad
        bad = self%pot%list_problem(text)
        call check_all(.not. bad, trim(text))
    end subroutine check_list_problem

    subroutine engine_check_valid(self, step, time)
        class(engine_t), intent(inout) :: self
        integer(i8), intent(in) :: step
        real(dp), intent(in) :: time
        character(len=512) :: text
        character(len=64) :: at
        logical :: bad
        bad = self%pot%invalid_state(text)
        write (at, '(a,i0,a,es12.5,1x,a)') ' at step ', step, ', time ', time, trim(self%units%time)
        call check_all(.not. bad, trim(text)//trim(at))
    end subroutine engine_check_valid

    !> Scale the box by mu(d) along each dimension about the origin, and with it every owned atom's
    !> position (x = mu x: the unwrapped positions scale too, image flags unchanged); with
    !> velocities also v = v / mu. The domain's bricks follow the box; the atoms are migrated and
    !> the halo and the neighbour list rebuilt. With keep_list, on the cell-list path with the
    !> displacement check (atom pairs, no inner list), the list and the halo are kept instead (rebuilt = .false.): the list's
    !> reference positions are scaled with the atoms and its skin test accounts for the scale since
    !> the build (neighbor_list%scale_reference); the caller then decides a build by that test or
    !> refreshes the ghosts, as after a drift. Collective (every rank passes the same mu).
    subroutine engine_scale_box(self, mu, velocities, keep_list, rebuilt)
        class(engine_t), intent(inout) :: self
        real(dp), intent(in) :: mu(3)
        logical, intent(in) :: velocities
        logical, intent(in), optional :: keep_list
        logical, intent(out), optional :: rebuilt
        integer :: i, d, n
        logical :: keep
        keep = .false.
        if (present(keep_list)) keep = keep_list .and. self%plan%pair_mode == pair_cells .and. &
                                       .not. (self%use_inner .or. self%plan%cluster_pairs) .and. self%list%check
        n = self%atoms%nlocal
        do i = 1, n
            do d = 1, self%box%dimension
                self%atoms%x(d, i) = mu(d)*self%atoms%x(d, i)
            end do
        end do
        if (velocities) then
            do i = 1, n
                do d = 1, self%box%dimension
                    self%atoms%v(d, i) = self%atoms%v(d, i)/mu(d)
                end do
            end do
        end if
        do d = 1, self%box%dimension
            self%box%lo(d) = mu(d)*self%box%lo(d)
            self%box%hi(d) = mu(d)*self%box%hi(d)
        end do
        self%box%length = self%box%hi - self%box%lo
        call self%dom%resize(self%box)
        if (present(rebuilt)) rebuilt = .not. keep
        if (keep) then
            call self%list%scale_reference(mu, n)
            ! wrapped images need the box more than twice the list's cutoff: otherwise copies again
            if (self%list%wrapped .and. .not. 2*self%list%cut < (1 - 1.0e-9_dp)*minval(self%box%length)) then
                call fresh_ghosts(self)
                self%list%wrapped = .false.
                self%inner%wrapped = .false.
            end if
        else
            call self%rebuild()
        end if
    end subroutine engine_scale_box

    !> A copy of what a trial move changes (restore_state returns to it exactly).
    subroutine engine_save_state(self, st)
        class(engine_t), intent(in) :: self
        type(engine_state_t), intent(inout) :: st
        st = self%engine_state_t
    end subroutine engine_save_state

    !> Back to a saved state (a rejected trial move): bitwise the state saved, the potential told
    !> of the restored atom order.
    subroutine engine_restore_state(self, st)
        class(engine_t), intent(inout) :: self
        type(engine_state_t), intent(in) :: st
        self%engine_state_t = st
        call self%atoms%refresh_rmass()
        call self%pot%on_rebuild(self%atoms)
    end subroutine engine_restore_state

end module terrace_engine
