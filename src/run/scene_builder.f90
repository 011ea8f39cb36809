!> Scene building: from the validated configuration to the atoms each rank owns, with their box,
!> masses, velocities and potential, the domain decomposition and the scene plan. The sources of a
!> scene: a lattice (&system lattice, cells), a LAMMPS data file, an atoms file, a frame of an H5MD
!> trajectory, or a checkpoint (which also carries the integrator's state and the forces, so that a
!> restart continues bitwise). Everything read from files is checked here, before the engine (and
!> any output) starts; the engine receives a built scene (terrace_engine's setup).
module terrace_scene_builder
    use terrace_kinds, only: dp, i8
    use terrace_config, only: config_t, max_types, is_unset
    use terrace_box, only: box_t
    use terrace_atoms, only: atoms_t
    use terrace_atom_table, only: atom_table_t, bcast_atom_table
    use terrace_data_coeffs, only: read_data_checked   ! data files with Pair Coeffs checked against &potential
    use terrace_atoms_file, only: read_atoms_file
    use terrace_lattice, only: lattice_basis, lattice_cell
    use terrace_velocities, only: create_velocities
    use terrace_domain, only: domain_t
    use terrace_potential, only: potential_t
    use terrace_potential_factory, only: make_potential
    use terrace_scene_planner, only: plan_scene
    use terrace_scene, only: scene_t
    use terrace_mpi_env, only: world, sum_all_i8, gather_counts
    use terrace_errors, only: stop_all, check_all
    use terrace_checkpoint, only: ckpt_data_t, read_checkpoint
    use terrace_named_values, only: named_values_t
    use terrace_namelist_text, only: deck_hash
    use terrace_h5md_reader, only: h5md_read_frame, h5md_frame_t
    use terrace_gmsh_mesh, only: mesh_t, read_gmsh
    use terrace_verlet_buffer, only: buffer_skin
    use, intrinsic :: iso_fortran_env, only: output_unit
    implicit none
    private

    !> A built scene, handed to the engine (which takes its parts over).

    public :: build_scene, scene_t

contains

    !> The scene of a deck: read or build the atoms, the box, the masses and the potential, set up
    !> the domain, hand every atom to the rank that owns it, make velocities, and plan. Collective.
    subroutine build_scene(cfg, self)
        type(scene_t), intent(out) :: self
        type(config_t), intent(inout) :: cfg      !< skin: the potential's preference when the deck gives none
        type(atom_table_t) :: table
        type(ckpt_data_t) :: ckpt
        logical :: from_table
        type(mesh_t) :: mesh
        real(dp) :: lo(3), hi(3), cell(3), cutghost
        integer :: ntypes, i

        self%restarted = len_trim(cfg%read_checkpoint) > 0
        from_table = (len_trim(cfg%read_data) > 0 .or. len_trim(cfg%atoms_file) > 0 .or. len_trim(cfg%read_h5md) > 0 &
                      .or. len_trim(cfg%mesh_file) > 0) .and. .not. self%restarted
        ntypes = 1
        if (self%restarted) then
            call load_checkpoint(cfg, ckpt, ntypes, lo, hi, table)
            ! a mesh is read again for its reference configuration, masses and connectivity; the
            ! checkpoint supplies positions, velocities and the integrator's state
            if (len_trim(cfg%mesh_file) > 0) call mesh_restart(cfg, ckpt, mesh, self)
        else if (len_trim(cfg%read_h5md) > 0) then
            call read_h5md_table(cfg, table)
            ntypes = table%ntypes
        else if (from_table) then
            call read_scene_table(cfg, self, table, mesh)
            ntypes = table%ntypes
        end if

        call scene_box(cfg, self, table, lo, hi, cell)
        if (from_table) call check_table_in_box(cfg, self%box, table)
        call scene_masses_and_potential(cfg, self, table, mesh, ntypes, from_table .or. self%restarted)

        ! ---- potential range (and the skin a term asks for when the deck gives none)
        if (cfg%nml%find('neighbor', 'skin') == 0 .and. self%pot%preferred_skin() > 0) cfg%skin = self%pot%preferred_skin()
        if (cfg%buffer_tolerance > 0) call size_buffer(self, cfg, table, ckpt, ntypes)
        self%cutmax = self%pot%cutoff()
        call check_range(cfg, self)

        ! ---- distribute atoms
        cutghost = self%pot%halo_reach() + max(cfg%skin, cfg%outer_skin)     ! (outer_skin: the built list's)
        if (self%restarted .and. ckpt%values%has('domain_grid_1')) then
            ! the interrupted run's processor grid (on as many ranks), so that it continues bitwise
            ! although a barostat may have changed which box edge is the longest
            call self%dom%setup(self%box, cutghost, grid=checkpoint_grid(ckpt))
        else
            call self%dom%setup(self%box, cutghost)
        end if
        if (self%restarted) then
            call place_checkpoint_atoms(self, cfg, ckpt)
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
        if (self%natoms == 0) call stop_all(trim(cfg%scene_source())//': the system is empty (no atoms)')

        if (cfg%temperature >= 0 .and. .not. self%restarted) then
            call create_velocities(self%atoms, cfg%units, cfg%temperature, cfg%seed, cfg%dimension, &
                                   .not. any(self%box%periodic(1:cfg%dimension)), self%natoms)
        end if
        if (cfg%reverse_velocities .and. .not. self%restarted) self%atoms%v(:, 1:self%atoms%nlocal) = -self%atoms%v(:, 1:self%atoms%nlocal)

        ! ---- plan
        call plan_scene(self%plan, cfg, self%box, self%natoms, world%nprocs, self%dom%dims, self%pot)
        self%source = cfg%scene_source()
        if (self%restarted) then
            ! the forces of the interrupted run (rows of the checkpoint are ids 1..N) and its state
            call move_alloc(ckpt%f, self%restart_f)
            self%restart_values = ckpt%values
        end if
    end subroutine build_scene

    !> The atoms of a data file or an atoms file (read on rank 0, shared with every rank), or of a
    !> mesh (its nodes), with at most max_types types.
    subroutine read_scene_table(cfg, self, table, mesh)
        type(config_t), intent(in) :: cfg
        type(scene_t), intent(inout) :: self
        type(atom_table_t), intent(inout) :: table
        type(mesh_t), intent(inout) :: mesh
        character(len=64) :: s1, s2
        if (world%rank == 0) then
            if (len_trim(cfg%read_data) > 0) then
                call read_data_checked(cfg, table)
            else if (len_trim(cfg%atoms_file) > 0) then
                call read_atoms_file(trim(cfg%atoms_file), table)
            end if
        end if
        if (len_trim(cfg%read_data) > 0 .or. len_trim(cfg%atoms_file) > 0) then
            call bcast_atom_table(table)
            if (.not. table%ok) call stop_all(trim(table%error))
        end if
        if (len_trim(cfg%mesh_file) > 0) then
            call mesh_scene(cfg, table, mesh, self%atoms, .false.)
            self%mesh_hash = mesh_fingerprint(mesh)
        end if
        if (table%ntypes > max_types) then
            write (s1, '(i0)') max_types
            write (s2, '(i0)') table%ntypes
            call stop_all(trim(cfg%scene_source())//': '//trim(s2)//' atom types: more atom types than Terrace supports (max '// &
                          trim(s1)//')')
        end if
    end subroutine read_scene_table

    !> The box: the checkpoint's (lo, hi as given), the lattice's (cell: its unit cell), the data or
    !> H5MD file's, or the deck's; free dimensions span the atoms' extent plus a margin (the cutoff,
    !> or half the mesh's size).
    subroutine scene_box(cfg, self, table, lo, hi, cell)
        type(config_t), intent(in) :: cfg
        type(scene_t), intent(inout) :: self
        type(atom_table_t), intent(in) :: table
        real(dp), intent(inout) :: lo(3), hi(3), cell(3)
        real(dp) :: margin
        integer :: d
        margin = max(cfg%cutoff, 1.0_dp)
        if (len_trim(cfg%mesh_file) > 0 .and. .not. self%restarted) &
            margin = 0.5_dp*maxval(maxval(table%x, 2) - minval(table%x, 2))
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
                    lo(d) = minval(table%x(d, :)) - margin
                    hi(d) = maxval(table%x(d, :)) + margin
                end if
            end do
        end if
        call self%box%set(lo, hi, cfg%periodic, cfg%dimension)
    end subroutine scene_box

    !> Every atom read lies in the box (and in the plane z = 0, at rest along z, in 2-D).
    subroutine check_table_in_box(cfg, box, table)
        type(config_t), intent(in) :: cfg
        type(box_t), intent(in) :: box
        type(atom_table_t), intent(in) :: table
        character(len=64) :: s1, s2
        integer :: i, d
        if (cfg%dimension == 2) then
            if (any(table%x(3, :) /= 0) .or. any(table%v(3, :) /= 0)) &
                call stop_all(trim(cfg%scene_source())//': a 2-D run needs z = 0 and vz = 0 for every atom')
        end if
        do i = 1, table%n
            do d = 1, cfg%dimension
                if (table%x(d, i) < box%lo(d) .or. table%x(d, i) > box%hi(d)) then
                    write (s1, '(i0)') table%id(i)
                    write (s2, '(es12.5)') table%x(d, i)
                    call stop_all(trim(cfg%scene_source())//': atom '//trim(s1)//' lies outside the box ('// &
                                  'xyz'(d:d)//' = '//trim(adjustl(s2))//')')
                end if
            end do
        end do
    end subroutine check_table_in_box

    !> The masses per type (the file's when read_masses, then the deck's), the potential, and a
    !> stop naming the first type without a mass.
    subroutine scene_masses_and_potential(cfg, self, table, mesh, ntypes, read_masses)
        type(config_t), intent(in) :: cfg
        type(scene_t), intent(inout) :: self
        type(atom_table_t), intent(in) :: table
        type(mesh_t), intent(in) :: mesh
        integer, intent(in) :: ntypes
        logical, intent(in) :: read_masses
        character(len=64) :: s1
        integer :: t
        allocate (self%atoms%mass(ntypes))
        self%atoms%ntypes = ntypes
        self%atoms%mass = -1
        if (read_masses) then
            if (table%has_masses) self%atoms%mass = table%mass(1:ntypes)
        end if
        if (len_trim(cfg%mesh_file) > 0) then
            self%atoms%mass(1) = table%mass(1)
            call make_potential(cfg, ntypes, self%atoms%mass, self%pot, mesh, table%x, self%atoms%mass_of_id, &
                                self%box%lo, self%box%hi)
            self%mesh_tet = mesh%tet
        else
            call make_potential(cfg, ntypes, self%atoms%mass, self%pot)
        end if
        do t = 1, ntypes
            if (cfg%mass(t) > 0) self%atoms%mass(t) = cfg%mass(t)
            if (.not. (self%atoms%mass(t) > 0)) then
                write (s1, '(i0)') t
                call stop_all(cfg%path//': &system: mass: type '//trim(s1)//' has no mass (give mass('//trim(s1)// &
                              ') in '//trim(cfg%units%mass)//', or a Masses section in the data file)')
            end if
        end do
    end subroutine scene_masses_and_potential

    !> Along each periodic dimension: the potential's cutoff within half the box, and cutoff + skin
    !> (and cutoff + outer_skin) within the box.
    subroutine check_range(cfg, self)
        type(config_t), intent(in) :: cfg
        type(scene_t), intent(in) :: self
        character(len=64) :: s1, s2
        character(len=:), allocatable :: key
        integer :: d
        do d = 1, cfg%dimension
            if (.not. self%box%periodic(d)) cycle
            if (self%cutmax > 0.5_dp*self%box%length(d)) then
                write (s1, '(es12.5)') self%cutmax
                write (s2, '(es12.5)') 0.5_dp*self%box%length(d)
                if (cfg%nml%gives_any('potential', 'cutoff pair_cutoff')) then
                    call stop_all(cfg%where('potential', 'cutoff')//' = '//trim(adjustl(s1))//': beyond half the '// &
                                  'periodic box along '//'xyz'(d:d)//' ('//trim(adjustl(s2))//'); use a larger box or '// &
                                  'a smaller cutoff')
                else      ! (a cutoff the potential's file sets, as EAM's: the box must grow)
                    call stop_all(cfg%where('potential', 'style')//" = '"//trim(cfg%potential)//"': its cutoff "// &
                                  trim(adjustl(s1))//' is beyond half the periodic box along '//'xyz'(d:d)//' ('// &
                                  trim(adjustl(s2))//'); use a larger box (&system cells or box_hi)')
                end if
            end if
            ! the built list's skin: outer_skin where there is one (with prune_every, the one buffer_tolerance
            ! sized for `every` steps)
            if (self%cutmax + max(cfg%skin, cfg%outer_skin) >= self%box%length(d)) then
                key = trim(merge('outer_skin', 'skin      ', cfg%outer_skin > cfg%skin))
                if (cfg%buffer_tolerance > 0) then
                    write (s1, '(es12.5)') max(cfg%skin, cfg%outer_skin)
                    call stop_all(cfg%where('neighbor', 'buffer_tolerance')//': the skin it needs ('// &
                                  trim(adjustl(s1))//') makes cutoff + skin reach the periodic box; use a larger '// &
                                  'tolerance, a smaller every or a larger box')
                end if
                call stop_all(cfg%where('neighbor', key)//': cutoff + '//key//' must be smaller than the periodic box')
            end if
        end do
    end subroutine check_range

    !> &neighbor buffer_tolerance: cfg%skin from the drift estimate (terrace_verlet_buffer) for the
    !> scene's atom counts per type, masses, box volume and temperature (the largest of &system
    !> temperature and the thermostat's targets; without any, the kinetic temperature of the velocities
    !> read), and cfg%buffer_drift, cfg%buffer_temperature for the run log. With prune_every, cfg%skin
    !> is the force pass's list's (for prune_every steps) and cfg%outer_skin the built list's (for
    !> every steps), each sized for half the tolerance (buffer_drift: the sum of both estimates). A
    !> restart takes them from its checkpoint (list_skin, ...), so that it continues the same run.
    subroutine size_buffer(self, cfg, table, ckpt, ntypes)
        type(scene_t), intent(in) :: self
        type(config_t), intent(inout) :: cfg
        type(atom_table_t), intent(in) :: table
        type(ckpt_data_t), intent(in) :: ckpt
        integer, intent(in) :: ntypes
        real(dp) :: count(ntypes), deriv(4, ntypes, ntypes), t_ref, ke, skin, drift, outer, outer_drift
        character(len=32) :: v
        real(dp), allocatable :: basis(:, :)
        integer :: a, b, i
        logical :: ok
        character(len=:), allocatable :: at
        at = cfg%where('neighbor', 'buffer_tolerance')
        do b = 1, ntypes
            do a = 1, ntypes
                deriv(:, a, b) = self%pot%cutoff_derivatives(a, b)
                if (deriv(1, a, b) <= 0) call stop_all(at//": &potential style = '"//trim(cfg%potential)//"' "// &
                    'gives no pair term with a cutoff for every pair of atom types, which the estimate needs (the '// &
                    'Lennard-Jones styles give one); give skin')
            end do
        end do
        t_ref = max(cfg%temperature, cfg%thermostat_temperature, cfg%thermostat_temperature_end)
        if (self%restarted) then
            ok = .true.
            cfg%skin = ckpt%values%get_r('list_skin', ok)
            cfg%buffer_drift = ckpt%values%get_r('list_buffer_drift', ok)
            cfg%buffer_temperature = ckpt%values%get_r('list_buffer_temperature', ok)
            if (cfg%prune_every > 0) cfg%outer_skin = ckpt%values%get_r('list_outer_skin', ok)
            if (.not. ok) call stop_all(at//': the checkpoint has no list_skin (it was not written by a run with '// &
                                        'buffer_tolerance)')
            return
        end if
        count = 0
        if (len_trim(cfg%lattice) > 0) then
            call lattice_basis(cfg%lattice, basis)
            count(1) = real(size(basis, 2), dp)*product(real(max(cfg%cells, 1), dp))
        else
            do i = 1, table%n
                count(table%type(i)) = count(table%type(i)) + 1
            end do
            if (t_ref < 0) then        ! the velocities read: 3 N k_B T = sum m v^2
                ke = 0
                do i = 1, table%n
                    ke = ke + self%atoms%mass(table%type(i))*sum(table%v(:, i)**2)
                end do
                t_ref = ke*cfg%units%mvv2e/(3*max(table%n, 1)*cfg%units%boltz)
            end if
        end if
        if (.not. (t_ref > 0)) call stop_all(at//': no temperature to size the buffer for (no &system temperature, '// &
            'no thermostat, and the velocities read are zero); give skin')
        if (cfg%prune_every > 0) then
            ! the built list for `every` steps, the force pass's list pruned from it for prune_every steps:
            ! each may miss pairs, so each gets half the tolerance
            call skin_for(0.5_dp*cfg%buffer_tolerance, cfg%prune_every, skin, drift)
            call skin_for(0.5_dp*cfg%buffer_tolerance, cfg%list_every, outer, outer_drift)
            write (v, '(g0.6)') skin
            if (.not. (outer > skin)) call stop_all(cfg%where('neighbor', 'prune_every')//': the tolerance needs '// &
                'no larger skin for every steps than for prune_every steps (both '//trim(v)//'); use prune_every = 0 '// &
                'or a larger every')
            cfg%outer_skin = outer
            drift = max(drift, 0.0_dp) + max(outer_drift, 0.0_dp)
        else
            call skin_for(cfg%buffer_tolerance, cfg%list_every, skin, drift)
        end if
        cfg%skin = skin; cfg%buffer_drift = drift; cfg%buffer_temperature = t_ref
    contains

        !> The estimate's skin (and its drift) for a tolerance and a list kept `every` steps, on this scene.
        subroutine skin_for(tolerance, every, skin_out, drift_out)
            real(dp), intent(in) :: tolerance
            integer, intent(in) :: every
            real(dp), intent(out) :: skin_out, drift_out
            call buffer_skin(tolerance, every, cfg%dt, cfg%units%boltz*t_ref, cfg%units%mvv2e, count, &
                             self%atoms%mass(1:ntypes), product(self%box%hi - self%box%lo), deriv, skin_out, drift_out)
        end subroutine skin_for
    end subroutine size_buffer

    !> The processor grid a checkpoint was written with.
    function checkpoint_grid(ckpt) result(grid)
        type(ckpt_data_t), intent(in) :: ckpt
        integer :: grid(3)
        logical :: ok
        ok = .true.
        grid = int([ckpt%values%get_i('domain_grid_1', ok), ckpt%values%get_i('domain_grid_2', ok), &
                    ckpt%values%get_i('domain_grid_3', ok)])
        if (.not. ok) grid = 0
    end function checkpoint_grid

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
            'deck (only &system read_checkpoint, &system restart_outputs and &run walltime_limit may differ from the '// &
            'deck that wrote it)')
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
    subroutine place_checkpoint_atoms(self, cfg, ckpt)
        type(scene_t), intent(inout) :: self
        type(config_t), intent(in) :: cfg
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
            call check_all(all(order > 0), trim(cfg%read_checkpoint)//': &system: read_checkpoint: damaged '// &
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

    !> A frame of an H5MD file as the starting scene: read in parallel (each rank a block of ids),
    !> then shared with every rank, which keeps the atoms it owns. The box is box_lo (default 0)
    !> plus the file's edges.
    subroutine read_h5md_table(cfg, table)
        use mpi_f08, only: MPI_Allgatherv, MPI_DOUBLE_PRECISION
        type(config_t), intent(in) :: cfg
        type(atom_table_t), intent(out) :: table
        type(h5md_frame_t) :: fr
        integer, allocatable :: counts(:), displs(:)
        real(dp), allocatable :: buf(:, :), mine(:, :)
        integer :: dimension, n, total, i
        real(dp) :: edges(3)
        logical :: ok, has_v
        character(len=1024) :: msg
        call h5md_read_frame(trim(cfg%read_h5md), world%comm, cfg%h5md_frame, fr, ok, msg)
        call check_all(ok, trim(cfg%read_h5md)//': &system: read_h5md: '//trim(msg))
        dimension = fr%dimension; edges = fr%edges; has_v = fr%has_velocity
        n = size(fr%ids)
        allocate (mine(11, n), counts(world%nprocs), displs(world%nprocs))
        do i = 1, n
            mine(1, i) = real(fr%ids(i), dp); mine(2, i) = real(fr%types(i), dp)
            mine(3:5, i) = fr%x(:, i); mine(6:8, i) = 0; mine(9:11, i) = 0
            if (has_v) mine(6:8, i) = fr%v(:, i)
            if (fr%has_image) mine(9:11, i) = real(fr%image(:, i), dp)
        end do
        call gather_counts(11*n, counts, displs)
        total = sum(counts)
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


    subroutine create_lattice_atoms(self, cfg, cell)
        type(scene_t), intent(inout) :: self
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

    !> A mesh as the scene: every rank reads the MSH file; nodes become atoms (id = node tag, type 1)
    !> at their reference positions, or at the positions and velocities of &system atoms_file when it
    !> is given (one line per node in tag order); lumped masses rho V0 / 4 per element and node
    !> (atoms%mass_of_id; type 1's mass is the mean); each body (physical volume) gets the rigid
    !> motion v = V_b + w_b x (x - c_b) about its centre of mass c_b. With masses_only (a restart)
    !> only the mesh and the masses are made: the atoms file and the rigid motion are not used.
    subroutine mesh_scene(cfg, table, mesh, atoms, masses_only)
        use terrace_config, only: max_bodies
        type(config_t), intent(in) :: cfg
        type(atom_table_t), intent(inout) :: table
        type(mesh_t), intent(out) :: mesh
        type(atoms_t), intent(inout) :: atoms
        logical, intent(in) :: masses_only
        real(dp), allocatable :: xref(:, :)
        integer, allocatable :: node_body(:)
        integer :: k, n
        logical :: current
        character(len=32) :: s1
        call read_gmsh(trim(cfg%mesh_file), mesh)
        call check_all(mesh%ok, trim(mesh%error))
        n = mesh%nnode
        current = len_trim(cfg%atoms_file) > 0 .and. .not. masses_only
        if (current .and. table%n /= n) then
            write (s1, '(i0,a,i0)') table%n, ' lines for ', n
            call stop_all(trim(cfg%atoms_file)//': &system: atoms_file: '//trim(s1)//' mesh nodes (one line per node, '// &
                          'in node-tag order)')
        end if
        allocate (xref(3, n))
        do k = 1, n
            xref(:, mesh%node_tag(k)) = mesh%x(:, k)
        end do
        if (any(mesh%body < 1 .or. mesh%body > max_bodies)) then
            write (s1, '(i0,a,i0)') mesh%body(findloc(mesh%body < 1 .or. mesh%body > max_bodies, .true., dim=1)), &
                ' is not in 1..', max_bodies
            call stop_all(trim(cfg%mesh_file)//': &system: mesh_file: physical volume tag '//trim(s1)// &
                          ' (each physical volume is a body, its tag the body number in &system velocity(:,b))')
        end if
        call lump_node_masses(cfg, mesh, xref, atoms, node_body)
        if (masses_only) return
        if (.not. current) then
            table%n = n
            allocate (table%x(3, n), table%v(3, n), table%type(n), table%image(3, n), table%id(n))
            table%x = xref
            table%v = 0
        end if
        table%type = 1
        table%image = 0
        table%id = [(int(k, i8), k=1, n)]
        table%ntypes = 1
        if (allocated(table%mass)) deallocate (table%mass)
        allocate (table%mass(1))
        table%mass(1) = sum(atoms%mass_of_id)/n
        table%has_masses = .true.
        call add_body_motion(cfg, node_body, atoms%mass_of_id, table)
    end subroutine mesh_scene

    !> Lumped masses (atoms%mass_of_id: a quarter of each tetrahedron's mass_density times its
    !> reference volume to each of its nodes) and each node's body (that of its first tetrahedron);
    !> a node in no tetrahedron stops the run.
    subroutine lump_node_masses(cfg, mesh, xref, atoms, node_body)
        use terrace_neohookean, only: det3
        type(config_t), intent(in) :: cfg
        type(mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: xref(:, :)
        type(atoms_t), intent(inout) :: atoms
        integer, allocatable, intent(out) :: node_body(:)
        real(dp) :: dm(3, 3), v0
        integer :: a, e
        allocate (atoms%mass_of_id(mesh%nnode), node_body(mesh%nnode))
        atoms%mass_of_id = 0
        node_body = 0
        do e = 1, mesh%ntet
            do a = 1, 3
                dm(:, a) = xref(:, mesh%tet(a + 1, e)) - xref(:, mesh%tet(1, e))
            end do
            v0 = abs(det3(dm))/6
            do a = 1, 4
                atoms%mass_of_id(mesh%tet(a, e)) = atoms%mass_of_id(mesh%tet(a, e)) + cfg%mass_density*v0/4
                if (node_body(mesh%tet(a, e)) == 0) node_body(mesh%tet(a, e)) = mesh%body(e)
            end do
        end do
        if (any(node_body == 0)) call stop_all(trim(cfg%mesh_file)//': &system: mesh_file: a node belongs to no '// &
                                               'tetrahedron (remove unused nodes: gmsh -save_all 0)')
        atoms%per_atom_mass = .true.
    end subroutine lump_node_masses

    !> The deck's rigid motion of each body (velocity(:,b), angular_velocity(:,b) about the body's
    !> centre of mass) added to the nodes' velocities; a body given a motion must be in the mesh.
    subroutine add_body_motion(cfg, node_body, mass_of_id, table)
        use terrace_config, only: max_bodies
        type(config_t), intent(in) :: cfg
        integer, intent(in) :: node_body(:)
        real(dp), intent(in) :: mass_of_id(:)
        type(atom_table_t), intent(inout) :: table
        real(dp) :: com(3, max_bodies), mb(max_bodies), w(3), r(3)
        character(len=32) :: s1
        integer :: k, b
        com = 0; mb = 0
        do k = 1, size(node_body)
            b = node_body(k)
            com(:, b) = com(:, b) + mass_of_id(k)*table%x(:, k)
            mb(b) = mb(b) + mass_of_id(k)
        end do
        do b = 1, max_bodies
            if (mb(b) > 0) com(:, b) = com(:, b)/mb(b)
            if (mb(b) == 0 .and. (any(cfg%body_velocity(:, b) /= 0) .or. any(cfg%body_angular_velocity(:, b) /= 0))) then
                write (s1, '(i0)') b
                call stop_all(cfg%where('system', 'velocity')//': body '//trim(s1)//' is given a velocity, but '// &
                              trim(cfg%mesh_file)//' has no body '//trim(s1)//' (its bodies: '//body_list(mb)//')')
            end if
        end do
        do k = 1, size(node_body)
            b = node_body(k)
            w = cfg%body_angular_velocity(:, b)
            r = table%x(:, k) - com(:, b)
            table%v(:, k) = table%v(:, k) + cfg%body_velocity(:, b) + [w(2)*r(3) - w(3)*r(2), w(3)*r(1) - w(1)*r(3), &
                                                                        w(1)*r(2) - w(2)*r(1)]
        end do
    end subroutine add_body_motion

    !> The bodies of a mesh (those of positive mass mb), '1, 2'.
    function body_list(mb) result(t)
        real(dp), intent(in) :: mb(:)
        character(len=:), allocatable :: t
        character(len=8) :: w
        integer :: j
        t = ''
        do j = 1, size(mb)
            if (mb(j) <= 0) cycle
            write (w, '(i0)') j
            if (len(t) > 0) t = t//', '
            t = t//trim(w)
        end do
    end function body_list

    !> A restart of a mesh scene: the mesh file is read again (reference configuration, lumped
    !> masses, connectivity) and must be the mesh the checkpoint was written for: the same nodes
    !> (count and ids 1..N) and the same fingerprint of connectivity and reference positions.
    subroutine mesh_restart(cfg, ckpt, mesh, self)
        type(config_t), intent(in) :: cfg
        type(ckpt_data_t), intent(in) :: ckpt
        type(mesh_t), intent(out) :: mesh
        type(scene_t), intent(inout) :: self
        type(atom_table_t) :: unused
        character(len=:), allocatable :: where
        character(len=64) :: s1, s2
        logical :: ok
        integer(i8) :: nodes, elements, hash
        where = cfg%where('system', 'read_checkpoint')//" = '"//trim(cfg%read_checkpoint)//"'"
        call mesh_scene(cfg, unused, mesh, self%atoms, .true.)
        self%mesh_hash = mesh_fingerprint(mesh)
        ok = .true.
        nodes = ckpt%values%get_i('mesh_nodes', ok)
        elements = ckpt%values%get_i('mesh_elements', ok)
        hash = ckpt%values%get_i('mesh_hash', ok)
        if (.not. ok) call stop_all(where//': the checkpoint holds no mesh (it was not written by a mesh scene)')
        if (nodes /= mesh%nnode .or. size(ckpt%id, kind=i8) /= mesh%nnode .or. elements /= mesh%ntet) then
            write (s1, '(i0,a,i0,a)') nodes, ' nodes and ', elements, ' tetrahedra'
            write (s2, '(i0,a,i0,a)') mesh%nnode, ' nodes and ', mesh%ntet, ' tetrahedra'
            call stop_all(where//': a checkpoint of a different mesh ('//trim(s1)//'; &system mesh_file = '''// &
                          trim(cfg%mesh_file)//''' has '//trim(s2)//')')
        end if
        if (hash /= self%mesh_hash) call stop_all(where//': a checkpoint of a different mesh (&system mesh_file = '''// &
            trim(cfg%mesh_file)//''' has the same numbers of nodes and tetrahedra but other connectivity or reference '// &
            'positions than the mesh the checkpoint was written for)')
    end subroutine mesh_restart

    !> A fingerprint of a mesh (node ids of every tetrahedron, reference positions by node tag, bit
    !> for bit): two polynomial hashes modulo primes, as the deck's (terrace_checkpoint: deck_hash).
    integer(i8) function mesh_fingerprint(mesh) result(h)
        type(mesh_t), intent(in) :: mesh
        integer(i8), parameter :: p1 = 2147483647_i8, p2 = 2147483629_i8
        integer(i8) :: h1, h2, bits
        integer :: e, a, k, d
        h1 = 13; h2 = 17
        do e = 1, mesh%ntet
            do a = 1, 4
                call mix(mesh%tet(a, e))
            end do
        end do
        do k = 1, mesh%nnode
            call mix(mesh%node_tag(k))
            do d = 1, 3
                bits = transfer(mesh%x(d, k), bits)
                call mix(bits)
            end do
        end do
        h = h1*2147483648_i8 + h2
    contains
        subroutine mix(v)
            integer(i8), intent(in) :: v
            integer(i8) :: lo, hi
            lo = iand(v, 2147483647_i8)             ! 31 low bits
            hi = iand(ishft(v, -31), 4294967295_i8)  ! the 33 high bits
            h1 = mod(mod(h1*131, p1) + lo, p1); h1 = mod(mod(h1*131, p1) + hi, p1)
            h2 = mod(mod(h2*257, p2) + lo, p2); h2 = mod(mod(h2*257, p2) + hi, p2)
        end subroutine mix
    end function mesh_fingerprint

end module terrace_scene_builder
