!> The engine state shared by every integrator: box, atoms, domain, neighbour list, potential,
!> scene plan and timers, and the operations the integrators are written in: rebuild (migrate,
!> sort, halo, list), refresh ghosts, force evaluation (with reverse sums), thermo sample.
module terrace_engine
    use terrace_kinds, only: dp, i8
    use terrace_config, only: config_t, max_types, is_unset
    use terrace_box, only: box_t
    use terrace_atoms, only: atoms_t
    use terrace_atom_table, only: atom_table_t, bcast_atom_table
    use terrace_data_coeffs, only: read_data_checked   ! issue 15: data files with Pair Coeffs
    use terrace_atoms_file, only: read_atoms_file
    use terrace_lattice, only: lattice_basis, lattice_cell
    use terrace_velocities, only: create_velocities, kinetic_energy
    use terrace_domain, only: domain_t
    use terrace_replicate, only: replicate_t
    use terrace_neighbor_list, only: neighbor_list_t
    use terrace_lj, only: lj_t
    use terrace_eam, only: eam_t
    use terrace_timers, only: timers_t, t_pair, t_neigh, t_comm, t_search
    use terrace_thermo, only: thermo_sample_t
    use terrace_scene_plan, only: plan_t, pair_all, pair_cells
    use terrace_mpi_env, only: world, sum_all, sum_all_i8, min_all, any_all
    use terrace_errors, only: stop_all, check_all, warn
    use terrace_checkpoint, only: ckpt_values_t, ckpt_data_t, read_checkpoint, deck_hash
    use, intrinsic :: iso_fortran_env, only: output_unit
    implicit none
    private

    type, public :: engine_t
        type(config_t) :: cfg
        type(box_t) :: box
        type(atoms_t) :: atoms
        type(domain_t) :: dom
        type(replicate_t) :: rep
        type(neighbor_list_t) :: list
        type(lj_t) :: lj
        type(eam_t) :: eam
        logical :: use_eam = .false.             !< EAM (density pass + halo of F'(rho)) instead of LJ
        real(dp) :: cutmax = 0                   !< the potential's largest cutoff (0: none)
        real(dp), allocatable :: halo_buf(:, :)  !< one-component copies of rho / F'(rho) for the halo
        type(plan_t) :: plan
        type(timers_t) :: timers
        integer(i8) :: natoms = 0
        real(dp) :: pe = 0, virial = 0          !< global, from the last energy evaluation
        integer(i8) :: force_evaluations = 0
        logical :: restarted = .false.           !< started from &system read_checkpoint
        type(ckpt_values_t) :: restart_values    !< the checkpoint's named values (integrator state)
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
        procedure :: report_warnings => engine_report_warnings
    end type engine_t

contains

    !> Everything from the validated configuration to the first forces. Collective.
    subroutine engine_setup(self, cfg)
        class(engine_t), intent(inout) :: self
        type(config_t), intent(in) :: cfg
        type(atom_table_t) :: table
        type(ckpt_data_t) :: ckpt
        logical :: from_table
        real(dp) :: lo(3), hi(3), cell(3), cutghost
        integer :: ntypes, d, t, i
        character(len=64) :: s1, s2

        self%cfg = cfg
        self%restarted = len_trim(cfg%read_checkpoint) > 0
        from_table = (len_trim(cfg%read_data) > 0 .or. len_trim(cfg%atoms_file) > 0 .or. len_trim(cfg%read_h5md) > 0) &
                     .and. .not. self%restarted
        ntypes = 1
        if (self%restarted) then
            call load_checkpoint(cfg, ckpt, ntypes, lo, hi, table)
        else if (len_trim(cfg%read_h5md) > 0) then
            call read_h5md_table(cfg, table)
            ntypes = table%ntypes
        else if (from_table) then
            if (world%rank == 0) then
                if (len_trim(cfg%read_data) > 0) then
                    call read_data_checked(cfg, table)
                else
                    call read_atoms_file(trim(cfg%atoms_file), table)
                end if
            end if
            call bcast_atom_table(table)
            if (.not. table%ok) call stop_all(trim(table%error))
            ntypes = table%ntypes
            if (ntypes > max_types) then
                write (s1, '(i0)') max_types
                write (s2, '(i0)') ntypes
                call stop_all(trim(source_name(cfg))//': '//trim(s2)//' atom types: more atom types than Terrace supports (max '// &
                              trim(s1)//')')
            end if
        end if

        ! ---- box
        if (self%restarted) then
            continue                         ! lo, hi: the checkpoint's
        else if (len_trim(cfg%lattice) > 0) then
            cell = lattice_cell(cfg%lattice, cfg%lattice_constant, cfg%density, cfg%dimension)
            lo = 0
            hi = cell*max(cfg%cells, 1)
        else if (len_trim(cfg%read_data) > 0 .or. len_trim(cfg%read_h5md) > 0) then
            lo = table%lo; hi = table%hi
        else
            do d = 1, cfg%dimension
                if (.not. is_unset(cfg%box_lo(d)) .and. .not. is_unset(cfg%box_hi(d))) then
                    lo(d) = cfg%box_lo(d); hi(d) = cfg%box_hi(d)
                    if (hi(d) <= lo(d)) call stop_all(cfg%where('system', 'box_hi')//': must be > box_lo')
                else if (cfg%periodic(d)) then
                    call stop_all(cfg%where('system', 'box_lo')//': a periodic dimension of an atoms_file scene '// &
                                  'needs box_lo and box_hi')
                else
                    lo(d) = minval(table%x(d, :)) - max(cfg%cutoff, 1.0_dp)
                    hi(d) = maxval(table%x(d, :)) + max(cfg%cutoff, 1.0_dp)
                end if
            end do
        end if
        call self%box%set(lo, hi, cfg%periodic, cfg%dimension)

        if (from_table) then
            if (cfg%dimension == 2) then
                if (any(table%x(3, :) /= 0) .or. any(table%v(3, :) /= 0)) &
                    call stop_all(trim(source_name(cfg))//': a 2-D run needs z = 0 and vz = 0 for every atom')
            end if
            do i = 1, table%n
                do d = 1, cfg%dimension
                    if (table%x(d, i) < self%box%lo(d) .or. table%x(d, i) > self%box%hi(d)) then
                        write (s1, '(i0)') table%id(i)
                        write (s2, '(es12.5)') table%x(d, i)
                        call stop_all(trim(source_name(cfg))//': atom '//trim(s1)//' lies outside the box ('// &
                                      'xyz'(d:d)//' = '//trim(adjustl(s2))//')')
                    end if
                end do
            end do
        end if

        ! ---- masses
        allocate (self%atoms%mass(ntypes))
        self%atoms%ntypes = ntypes
        self%atoms%mass = -1
        if (from_table .or. self%restarted) then
            if (table%has_masses) self%atoms%mass = table%mass(1:ntypes)
        end if
        self%use_eam = cfg%potential(1:3) == 'eam'
        if (self%use_eam) then
            block
                logical :: ok
                character(len=1024) :: msg
                call self%eam%read(trim(cfg%potential), trim(cfg%potential_file), cfg%elements(1:max(ntypes, 1)), ntypes, &
                                   ok, msg)
                call check_all(ok, trim(msg)//' (&potential file)')
            end block
            do t = 1, ntypes
                if (.not. (self%atoms%mass(t) > 0)) self%atoms%mass(t) = self%eam%mass(t)
            end do
        end if
        do t = 1, ntypes
            if (cfg%mass(t) > 0) self%atoms%mass(t) = cfg%mass(t)
            if (.not. (self%atoms%mass(t) > 0)) then
                write (s1, '(i0)') t
                call stop_all(cfg%path//': &system: mass: type '//trim(s1)//' has no mass (give mass('//trim(s1)// &
                              ') in '//trim(cfg%units%mass)//', or a Masses section in the data file)')
            end if
        end do

        ! ---- potential tables
        if (self%use_eam) then
            self%cutmax = self%eam%cutmax
        else
            call setup_lj(self, cfg, ntypes)
        end if
        do d = 1, cfg%dimension
            if (.not. self%box%periodic(d)) cycle
            if (self%cutmax > 0.5_dp*self%box%length(d)) then
                write (s1, '(es12.5)') self%cutmax
                write (s2, '(es12.5)') 0.5_dp*self%box%length(d)
                call stop_all(cfg%where('potential', 'cutoff')//' = '//trim(adjustl(s1))//': beyond half the periodic '// &
                              'box along '//'xyz'(d:d)//' ('//trim(adjustl(s2))//'); use a larger box or a smaller cutoff')
            end if
            if (self%cutmax + cfg%skin >= self%box%length(d)) &
                call stop_all(cfg%where('neighbor', 'skin')//': cutoff + skin must be smaller than the periodic box')
        end do

        ! ---- distribute atoms
        cutghost = self%cutmax + cfg%skin
        call self%dom%setup(self%box, cutghost)
        if (self%restarted) then
            call place_checkpoint_atoms(self, ckpt)
        else if (len_trim(cfg%lattice) > 0) then
            call create_lattice_atoms(self, cfg, cell)
        else
            do i = 1, table%n
                if (self%dom%owns(table%x(:, i))) &
                    call self%atoms%append(table%x(:, i), table%v(:, i), table%type(i), table%id(i), table%image(:, i))
            end do
        end if
        self%natoms = self%atoms%nlocal
        call sum_all_i8(self%natoms)
        if (self%natoms == 0) call stop_all(trim(source_name(cfg))//': the system is empty (no atoms)')

        if (cfg%temperature >= 0 .and. .not. self%restarted) then
            call create_velocities(self%atoms, cfg%units, cfg%temperature, cfg%seed, cfg%dimension, &
                                   .not. any(self%box%periodic(1:cfg%dimension)), self%natoms)
        end if
        if (cfg%reverse_velocities .and. .not. self%restarted) self%atoms%v(:, 1:self%atoms%nlocal) = -self%atoms%v(:, 1:self%atoms%nlocal)

        ! ---- plan
        self%plan%natoms = self%natoms
        self%plan%nprocs = world%nprocs
        self%plan%dims = self%dom%dims
        self%plan%pair_mode = pair_cells
        if (.not. self%use_eam) then
            if (cfg%list == 'all_pairs' .or. self%lj%no_cutoff) then
                self%plan%pair_mode = pair_all
            else if (cfg%list == 'auto' .and. .not. any(self%box%periodic(1:cfg%dimension)) .and. &
                     self%natoms <= self%plan%all_pairs_max) then
                self%plan%pair_mode = pair_all
            end if
        end if
        call self%plan%finish(cfg, self%box, self%cutmax)

        self%list%dimension = cfg%dimension
        if (self%plan%pair_mode == pair_cells) call self%list%init(self%cutmax, cfg%skin, cfg%dimension)
        ! EAM ray passes need each owned atom's whole neighbourhood (see terrace_eam's eam_ray)
        self%list%want_below = self%use_eam .and. cfg%integrator == 'energy_stepping'
        call self%rebuild()
        call check_overlaps(self)
        call self%compute_forces(.true.)
        if (self%restarted) then
            ! the forces of the interrupted run (rows of the checkpoint are ids 1..N)
            do i = 1, self%atoms%nlocal
                self%atoms%f(:, i) = ckpt%f(:, self%atoms%id(i))
            end do
            self%restart_values = ckpt%values
        end if
    end subroutine engine_setup

    !> Read &system read_checkpoint (every rank), check that it belongs to this deck, and return
    !> the number of atom types, the box and the masses (in table). Collective.
    subroutine load_checkpoint(cfg, ckpt, ntypes, lo, hi, table)
        type(config_t), intent(in) :: cfg
        type(ckpt_data_t), intent(out) :: ckpt
        integer, intent(out) :: ntypes
        real(dp), intent(out) :: lo(3), hi(3)
        type(atom_table_t), intent(inout) :: table
        logical :: ok
        character(len=512) :: msg
        character(len=16) :: tag
        integer :: d, t
        character(len=:), allocatable :: where
        where = cfg%where('system', 'read_checkpoint')//" = '"//trim(cfg%read_checkpoint)//"'"
        call read_checkpoint(trim(cfg%read_checkpoint), ckpt, ok, msg)
        call check_all(ok, where//': '//trim(msg))
        if (ckpt%deck_hash /= deck_hash(cfg%nml)) call stop_all(where//': the checkpoint was written by a different '// &
            'deck (only &system read_checkpoint and &run walltime_limit may differ from the deck that wrote it)')
        ok = .true.
        do d = 1, 3
            write (tag, '(i0)') d
            lo(d) = ckpt%values%get_r('box_lo_'//trim(tag), ok)
            hi(d) = ckpt%values%get_r('box_hi_'//trim(tag), ok)
        end do
        ntypes = int(ckpt%values%get_i('ntypes', ok))
        if (ok .and. ntypes >= 1 .and. ntypes <= max_types) then
            allocate (table%mass(ntypes))
            do t = 1, ntypes
                write (tag, '(i0)') t
                table%mass(t) = ckpt%values%get_r('mass_'//trim(tag), ok)
            end do
            table%has_masses = .true.
        else
            ok = .false.
        end if
        if (ok) ok = all(ckpt%id == [(int(d, i8), d=1, size(ckpt%id))])
        call check_all(ok, where//': damaged checkpoint (box, masses or atom ids missing)')
    end subroutine load_checkpoint

    !> Every atom back in its slot (rank and place in that rank's arrays) when the rank count is the
    !> one that wrote the checkpoint; otherwise to the rank that owns its position.
    subroutine place_checkpoint_atoms(self, ckpt)
        type(engine_t), intent(inout) :: self
        type(ckpt_data_t), intent(in) :: ckpt
        integer, allocatable :: order(:)
        integer :: n, k, i
        if (ckpt%nprocs == world%nprocs) then
            n = count(ckpt%slot(1, :) == world%rank)
            allocate (order(n))
            order = 0
            do k = 1, size(ckpt%id)
                if (ckpt%slot(1, k) /= world%rank) cycle
                i = int(ckpt%slot(2, k))
                if (i >= 1 .and. i <= n) order(i) = k
            end do
            call check_all(all(order > 0), trim(self%cfg%read_checkpoint)//': &system: read_checkpoint: damaged '// &
                           'checkpoint (atom slots)')
        else
            if (world%rank == 0) write (output_unit, '(a,i0,a)') '  note       : the checkpoint was written on ', &
                ckpt%nprocs, ' ranks: the continuation is a valid run but not bitwise the uninterrupted one'
            order = pack([(k, k=1, size(ckpt%id))], [(self%dom%owns(ckpt%x(:, k)), k=1, size(ckpt%id))])
        end if
        do k = 1, size(order)
            i = order(k)
            call self%atoms%append(ckpt%x(:, i), ckpt%v(:, i), ckpt%type(i), ckpt%id(i), ckpt%image(:, i))
        end do
    end subroutine place_checkpoint_atoms

    !> LJ tables: per-pair epsilon, sigma (geometric mixing where a pair is not given) and cutoff.
    subroutine setup_lj(self, cfg, ntypes)
        type(engine_t), intent(inout) :: self
        type(config_t), intent(in) :: cfg
        integer, intent(in) :: ntypes
        real(dp) :: cut(max_types, max_types), eps(max_types, max_types), sig(max_types, max_types)
        integer :: t, i
        character(len=64) :: s1
        do t = 1, ntypes
            if (is_unset(cfg%epsilon(t, t)) .or. is_unset(cfg%sigma(t, t))) then
                write (s1, '(i0)') t
                call stop_all(cfg%path//': &potential: epsilon: type '//trim(s1)//' needs epsilon('//trim(s1)//','// &
                              trim(s1)//') and sigma('//trim(s1)//','//trim(s1)//')')
            end if
        end do
        do t = 1, ntypes
            do i = 1, ntypes
                eps(i, t) = pick(cfg%epsilon, i, t, sqrt(cfg%epsilon(i, i)*cfg%epsilon(t, t)))
                sig(i, t) = pick(cfg%sigma, i, t, sqrt(cfg%sigma(i, i)*cfg%sigma(t, t)))
                cut(i, t) = pick(cfg%pair_cutoff, i, t, cfg%cutoff)
            end do
        end do
        call self%lj%setup(ntypes, eps, sig, cut, cfg%shift, cfg%potential == 'lj/smooth/linear')
        self%cutmax = self%lj%cutmax
    end subroutine setup_lj

    !> A frame of an H5MD file as the starting scene: read in parallel (each rank a block of ids),
    !> then shared with every rank, which keeps the atoms it owns. The box is box_lo (default 0)
    !> plus the file's edges.
    subroutine read_h5md_table(cfg, table)
        use terrace_h5md, only: h5md_read_frame
        use mpi_f08, only: MPI_Allgather, MPI_Allgatherv, MPI_INTEGER, MPI_INTEGER8, MPI_DOUBLE_PRECISION
        type(config_t), intent(in) :: cfg
        type(atom_table_t), intent(out) :: table
        integer(i8), allocatable :: ids(:)
        integer, allocatable :: types(:), image(:, :), counts(:), displs(:)
        real(dp), allocatable :: x(:, :), v(:, :), buf(:, :), mine(:, :)
        integer(i8) :: natoms, step
        integer :: dimension, n, total, r, i
        real(dp) :: time, edges(3)
        logical :: ok, has_v, has_image
        character(len=1024) :: msg
        call h5md_read_frame(trim(cfg%read_h5md), world%comm, cfg%h5md_frame, natoms, dimension, ids, types, x, v, image, &
                             step, time, ok, msg, has_velocity=has_v, has_image=has_image, edges=edges)
        call check_all(ok, trim(cfg%read_h5md)//': &system: read_h5md: '//trim(msg))
        n = size(ids)
        allocate (mine(11, n), counts(world%nprocs), displs(world%nprocs))
        do i = 1, n
            mine(1, i) = real(ids(i), dp); mine(2, i) = real(types(i), dp)
            mine(3:5, i) = x(:, i); mine(6:8, i) = 0; mine(9:11, i) = 0
            if (has_v) mine(6:8, i) = v(:, i)
            if (has_image) mine(9:11, i) = real(image(:, i), dp)
        end do
        call MPI_Allgather(11*n, 1, MPI_INTEGER, counts, 1, MPI_INTEGER, world%comm)
        total = 0
        do r = 1, world%nprocs
            displs(r) = total; total = total + counts(r)
        end do
        allocate (buf(11, total/11))
        call MPI_Allgatherv(mine, 11*n, MPI_DOUBLE_PRECISION, buf, counts, displs, MPI_DOUBLE_PRECISION, world%comm)
        table%n = total/11
        allocate (table%x(3, table%n), table%v(3, table%n), table%type(table%n), table%image(3, table%n), &
                  table%id(table%n))
        table%id = nint(buf(1, :), i8); table%type = nint(buf(2, :)); table%x = buf(3:5, :); table%v = buf(6:8, :)
        table%image = nint(buf(9:11, :))
        table%ntypes = maxval(table%type)
        allocate (table%mass(table%ntypes)); table%mass = -1
        table%has_velocities = has_v
        table%lo = 0
        do i = 1, 3
            if (.not. is_unset(cfg%box_lo(i))) table%lo(i) = cfg%box_lo(i)
        end do
        table%hi = table%lo + edges
        if (dimension == 2) table%x(3, :) = 0
        ! frames hold positions as the run had them (up to skin/2 outside a periodic box): wrap
        do i = 1, dimension
            if (.not. cfg%periodic(i)) cycle
            where (table%x(i, :) < table%lo(i))
                table%x(i, :) = table%x(i, :) + edges(i); table%image(i, :) = table%image(i, :) - 1
            elsewhere (table%x(i, :) >= table%hi(i))
                table%x(i, :) = table%x(i, :) - edges(i); table%image(i, :) = table%image(i, :) + 1
            end where
        end do
        table%has_box = .true.
        if (dimension /= cfg%dimension) call stop_all(trim(cfg%read_h5md)//': &system: read_h5md: the file is '// &
            merge('2-D', '3-D', dimension == 2)//', the run is not (&run dimension)')
    end subroutine read_h5md_table

    pure real(dp) function pick(table, i, j, fallback) result(v)
        real(dp), intent(in) :: table(:, :), fallback
        integer, intent(in) :: i, j
        if (.not. is_unset(table(i, j))) then
            v = table(i, j)
        else if (.not. is_unset(table(j, i))) then
            v = table(j, i)
        else
            v = fallback
        end if
    end function pick

    function source_name(cfg) result(s)
        type(config_t), intent(in) :: cfg
        character(len=:), allocatable :: s
        if (len_trim(cfg%read_h5md) > 0) then
            s = trim(cfg%read_h5md)//': &system: read_h5md'
        else if (len_trim(cfg%read_data) > 0) then
            s = trim(cfg%read_data)//': &system: read_data'
        else if (len_trim(cfg%atoms_file) > 0) then
            s = trim(cfg%atoms_file)//': &system: atoms_file'
        else
            s = cfg%path//': &system: lattice'
        end if
    end function source_name

    subroutine create_lattice_atoms(self, cfg, cell)
        type(engine_t), intent(inout) :: self
        type(config_t), intent(in) :: cfg
        real(dp), intent(in) :: cell(3)
        real(dp), allocatable :: basis(:, :)
        integer :: i, j, k, b, nb, nc(3)
        integer :: lo(3), hi(3), d
        real(dp) :: x(3)
        integer(i8) :: id
        call lattice_basis(cfg%lattice, basis)
        nb = size(basis, 2)
        nc = max(cfg%cells, 1)
        if (cfg%dimension == 2) nc(3) = 1
        ! only the cells that can hold owned sites
        do d = 1, 3
            lo(d) = max(0, int(floor((self%dom%sublo(d) - self%box%lo(d))/cell(d))) - 1)
            hi(d) = min(nc(d) - 1, int(ceiling((self%dom%subhi(d) - self%box%lo(d))/cell(d))) + 1)
        end do
        if (cfg%dimension == 2) then
            lo(3) = 0; hi(3) = 0
        end if
        do k = lo(3), hi(3)
            do j = lo(2), hi(2)
                do i = lo(1), hi(1)
                    do b = 1, nb
                        x = self%box%lo + ([real(dp) :: i, j, k] + basis(:, b))*cell
                        if (cfg%dimension == 2) x(3) = 0
                        if (.not. self%dom%owns(x)) cycle
                        id = 1 + (b - 1) + int(nb, i8)*(i + int(nc(1), i8)*(j + int(nc(2), i8)*k))
                        call self%atoms%append(x, [0.0_dp, 0.0_dp, 0.0_dp], 1, id, [0, 0, 0])
                    end do
                end do
            end do
        end do
    end subroutine create_lattice_atoms

    !> Degrees of freedom for the temperature, d N - d (as LAMMPS).
    pure real(dp) function engine_dof(self)
        class(engine_t), intent(in) :: self
        engine_dof = real(self%cfg%dimension, dp)*(real(self%natoms, dp) - 1)
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
        call self%list%setup_bins(lo, hi, n)
        call self%list%sort_owned(self%atoms)
        call self%timers%stop(t_neigh)
        call self%timers%start(t_comm)
        call self%dom%borders(self%atoms)
        call self%timers%stop(t_comm)
        call self%timers%start(t_neigh)
        call self%list%build(self%atoms)
        call self%timers%stop(t_neigh)
    end subroutine engine_rebuild

    !> Bring ghost positions up to date (no rebuild).
    subroutine engine_refresh_ghosts(self)
        class(engine_t), intent(inout) :: self
        call self%timers%start(t_comm)
        if (self%plan%pair_mode == pair_all) then
            if (world%nprocs > 1) call self%rep%gather(self%atoms, self%atoms%x)
        else
            call self%dom%forward(self%atoms%x, .true.)
        end if
        call self%timers%stop(t_comm)
    end subroutine engine_refresh_ghosts

    !> Forces on owned atoms (ghost contributions summed back); with want_energy also the global
    !> potential energy and virial.
    subroutine engine_compute_forces(self, want_energy)
        class(engine_t), intent(inout) :: self
        logical, intent(in) :: want_energy
        real(dp) :: ew(2)
        integer :: nall
        call self%timers%start(t_pair)
        nall = self%atoms%nall()
        self%atoms%f(:, 1:nall) = 0
        if (self%use_eam) then
            call eam_forces(self, want_energy, ew)
        else if (self%plan%pair_mode == pair_all) then
            call self%lj%compute_all_pairs(self%atoms, ew(1), ew(2))
        else
            call self%lj%compute(self%atoms, self%list, want_energy, ew(1), ew(2))
        end if
        call self%timers%stop(t_pair)
        if (self%plan%pair_mode == pair_cells) then
            call self%timers%start(t_comm)
            call self%dom%reverse(self%atoms%f)
            call self%timers%stop(t_comm)
        end if
        if (want_energy) then
            call self%timers%start(t_comm)
            call sum_all(ew)
            call self%timers%stop(t_comm)
            self%pe = ew(1); self%virial = ew(2)
        end if
        self%force_evaluations = self%force_evaluations + 1
    end subroutine engine_compute_forces

    !> EAM: density pass over the half list, reverse sum of the ghost densities into their owners,
    !> F'(rho) of the owned atoms, forward copy of F'(rho) to the ghosts, force pass. ew = (pair +
    !> embedding energy, virial) of this rank. The halo calls are timed as communication.
    subroutine eam_forces(self, want_energy, ew)
        type(engine_t), intent(inout) :: self
        logical, intent(in) :: want_energy
        real(dp), intent(out) :: ew(2)
        integer :: nall
        real(dp) :: e_embed, e_pair, w
        nall = self%atoms%nall()
        call self%eam%density(self%atoms, self%list)
        call self%timers%stop(t_pair)
        call self%timers%start(t_comm)
        if (allocated(self%halo_buf)) then
            if (size(self%halo_buf, 2) < nall) deallocate (self%halo_buf)
        end if
        if (.not. allocated(self%halo_buf)) allocate (self%halo_buf(1, nall + nall/4 + 16))
        self%halo_buf(1, 1:nall) = self%eam%rho(1:nall)
        call self%dom%reverse(self%halo_buf(:, 1:nall))
        self%eam%rho(1:self%atoms%nlocal) = self%halo_buf(1, 1:self%atoms%nlocal)
        call self%timers%stop(t_comm)
        call self%timers%start(t_pair)
        call self%eam%embed(self%atoms, want_energy, e_embed)
        call self%timers%stop(t_pair)
        call self%timers%start(t_comm)
        self%halo_buf(1, 1:nall) = self%eam%fp(1:nall)
        call self%dom%forward(self%halo_buf(:, 1:nall), .false.)
        self%eam%fp(1:nall) = self%halo_buf(1, 1:nall)
        call self%timers%stop(t_comm)
        call self%timers%start(t_pair)
        call self%eam%force(self%atoms, self%list, want_energy, e_pair, w)
        ew = [0.0_dp, w]
        if (want_energy) ew(1) = e_embed + e_pair
    end subroutine eam_forces

    !> Thermo quantities from the current velocities and the last energy evaluation.
    function engine_sample(self, step, time) result(s)
        class(engine_t), intent(inout) :: self
        integer(i8), intent(in) :: step
        real(dp), intent(in) :: time
        type(thermo_sample_t) :: s
        real(dp) :: dof, pl(6), m, r(3)
        integer :: i
        s%step = step; s%time = time
        s%ke = kinetic_energy(self%atoms, self%cfg%units)
        pl = 0
        do i = 1, self%atoms%nlocal
            m = self%atoms%mass(self%atoms%type(i))
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
        if (dof > 0) s%temp = 2*s%ke/(dof*self%cfg%units%boltz)
        s%press = (2*s%ke + self%virial)/(self%box%dimension*self%box%volume())*self%cfg%units%nktv2p
    end function engine_sample

    !> Energy, its first two derivatives along the ray x + s v, and the virial, summed over all
    !> ranks: out = (V, dV/ds, d2V/ds2, W). One pass over the pairs, one global sum.
    subroutine engine_ray_pass(self, s, out)
        class(engine_t), intent(inout) :: self
        real(dp), intent(in) :: s
        real(dp), intent(out) :: out(4)
        call self%timers%start(t_search)
        if (self%use_eam) then
            call self%eam%ray(self%atoms, self%list, s, out)
        else if (self%plan%pair_mode == pair_all) then
            call self%lj%ray_all_pairs(self%atoms, s, out)
        else
            call self%lj%ray(self%atoms, self%list, s, out)
        end if
        call self%timers%stop(t_search)
        call self%timers%start(t_comm)
        call sum_all(out)
        call self%timers%stop(t_comm)
    end subroutine engine_ray_pass

    !> Straight-line motion of every atom, owned and ghost: x += s v.
    subroutine engine_drift(self, s)
        class(engine_t), intent(inout) :: self
        real(dp), intent(in) :: s
        integer :: n
        n = self%atoms%nall()
        self%atoms%x(:, 1:n) = self%atoms%x(:, 1:n) + s*self%atoms%v(:, 1:n)
    end subroutine engine_drift

    !> Ghost positions and velocities from their owners (after a velocity jump).
    subroutine engine_sync_ghosts(self)
        class(engine_t), intent(inout) :: self
        call self%timers%start(t_comm)
        if (self%plan%pair_mode == pair_all) then
            if (world%nprocs > 1) then
                call self%rep%gather(self%atoms, self%atoms%x)
                call self%rep%gather(self%atoms, self%atoms%v)
            end if
        else
            call self%dom%forward(self%atoms%x, .true.)
            call self%dom%forward(self%atoms%v, .false.)
        end if
        call self%timers%stop(t_comm)
    end subroutine engine_sync_ghosts

    !> Earliest time (from now, this rank's atoms) at which an owned atom's displacement since the
    !> last list build reaches skin/2, moving in a straight line: the root of
    !> |d + s v|^2 = (skin/2)^2. Huge when there is no list.
    real(dp) function engine_list_expiry(self) result(t)
        class(engine_t), intent(in) :: self
        integer :: i
        real(dp) :: r2, a, b, c, d(3), disc
        t = huge(1.0_dp)
        if (self%plan%pair_mode == pair_all) return
        r2 = (0.5_dp*self%list%skin)**2
        do i = 1, self%atoms%nlocal
            d = self%atoms%x(:, i) - self%list%xhold(:, i)
            a = sum(self%atoms%v(:, i)**2)
            if (a <= 0) cycle
            b = sum(d*self%atoms%v(:, i))
            c = sum(d*d) - r2
            if (c >= 0) then
                t = 0
                return
            end if
            disc = b*b - a*c
            ! positive root of a s^2 + 2 b s + c = 0 (c < 0), without cancellation
            if (b >= 0) then
                t = min(t, -c/(b + sqrt(disc)))
            else
                t = min(t, (-b + sqrt(disc))/a)
            end if
        end do
    end function engine_list_expiry

    !> Warnings gathered during the run, printed once by rank 0 (collective): EAM tables left.
    subroutine engine_report_warnings(self)
        class(engine_t), intent(inout) :: self
        logical :: flags(2)
        character(len=512) :: text
        if (.not. self%use_eam) return
        flags = [self%eam%rho_outside, self%eam%r_table_short]
        call any_all(flags(1)); call any_all(flags(2))
        if (self%eam%warning(text)) then
            if (world%rank == 0) call warn(trim(text))
        else if (any(flags) .and. world%rank == 0) then
            call warn('eam: some ranks left the tabulated range of the potential (densities or distances); '// &
                      'values were continued as LAMMPS does')
        end if
    end subroutine engine_report_warnings

    !> Refuse a start with atoms on top of each other (closer than sigma/4).
    subroutine check_overlaps(self)
        type(engine_t), intent(inout) :: self
        real(dp) :: rmin_ratio, rsq, sig
        integer :: i, k, j, jend
        character(len=32) :: s
        rmin_ratio = huge(1.0_dp)
        do i = 1, self%atoms%nlocal
            if (self%plan%pair_mode == pair_cells) then
                k = self%list%first(i); jend = self%list%first(i + 1) - 1
            else
                k = i + 1; jend = self%atoms%nall()
            end if
            do while (k <= jend)
                if (self%plan%pair_mode == pair_cells) then
                    j = self%list%neigh(k)
                else
                    j = k
                end if
                rsq = sum((self%atoms%x(:, i) - self%atoms%x(:, j))**2)
                if (self%use_eam) then
                    sig = 0.4_dp*self%cutmax        ! a contact distance for EAM (about the nearest neighbour)
                else
                    sig = (self%lj%lj3(self%atoms%type(i), self%atoms%type(j))/ &
                           max(self%lj%lj4(self%atoms%type(i), self%atoms%type(j)), tiny(1.0_dp)))**(1.0_dp/6)
                end if
                rmin_ratio = min(rmin_ratio, sqrt(rsq)/sig)
                k = k + 1
            end do
        end do
        call min_all(rmin_ratio)
        write (s, '(es10.3)') rmin_ratio
        call check_all(.not. (rmin_ratio < 0.25_dp), trim(source_name(self%cfg))//': overlapping atoms (closest pair '// &
                       'at '//trim(adjustl(s))//' sigma; at least sigma/4 is required)')
    end subroutine check_overlaps

end module terrace_engine
