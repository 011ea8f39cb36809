!> The run configuration: every namelist group read, checked and converted once.
!>
!> Groups and keys (documented in doc/input.md):
!>   &run        units, dimension, n_steps, run_time, seed
!>   &system     read_data | lattice (+ lattice_constant or density, cells) | atoms_file (+ box_lo,
!>               box_hi), periodic, mass, temperature
!>   &potential  style, epsilon, sigma, cutoff, pair_cutoff, shift, precision
!>   &integrator style, dt
!>   &neighbor   skin, list, every, check, buffer_tolerance, outer_skin, prune_every, images
!>   &output     thermo_every, thermo_interval, thermo_file, forces_file
!>   &thermostat style, temperature, temperature_end, damping, chain_length, seed, zero_momentum, interval
!>   &barostat   style, pressure, damping, compressibility, couple
!>   &minimize   style, etol, ftol, max_iterations, max_evaluations
!> Every key is read on its own, so that an error names file, line, group and key.
module terrace_config
    use terrace_kinds, only: dp, i8
    use terrace_units, only: units_t, make_units, unit_names_allowed
    use terrace_namelist_text, only: namelist_file_t, parse_namelist_text, lower, at_line
    use terrace_errors, only: stop_all
    use terrace_files, only: read_input_text
    use terrace_mpi_env, only: world
    use terrace_file_ops, only: path_kind, resolve_path, directory_of, path_regular, path_directory, path_special
    use terrace_text, only: int_text, sci_text, quoted_list, has_word, style_row
    use terrace_potential_styles, only: potential_style_t, default_potential_style, &
                                        pots => potential_table
    use terrace_integrator_styles, only: integrator_style_t, default_integrator_style, &
                                         integs => integrator_table
    use terrace_minimize_styles, only: minimize_style_t, mins => minimize_table
    use terrace_thermostat, only: thermostat_t, thermostat_params_t
    use terrace_thermostat_factory, only: is_thermostat_style, new_thermostat, thermostat_styles, &
                                          thermostat_styles_for_events, thermostat_styles_with_chain, &
                                          thermostat_styles_colliding, thermostat_names_with_chain
    implicit none
    private

    !> The most calendar entries (samples, frames, events, thermostat actions) a run may schedule
    !> by its intervals, and the longest Nose-Hoover chain
    real(dp), parameter :: max_events = 1.0e12_dp
    integer, parameter :: max_chain = 100

    integer, parameter, public :: max_types = 8
    integer, parameter, public :: max_bodies = 16  !< physical volumes of a mesh with their own rigid motion
    integer, parameter, public :: max_walls = 16   !< planes of &potential wall_planes
    integer, parameter, public :: max_volumes = 64 !< volume entities of a mesh with a material of their own
    !> Longest file name a key may hold (Linux PATH_MAX); a longer one is refused, never truncated.
    integer, parameter, public :: path_max = 4096
    real(dp), parameter :: unset = -huge(1.0_dp)

    type, public :: config_t
        character(len=:), allocatable :: path
        type(namelist_file_t) :: nml
        ! &run
        type(units_t) :: units
        integer :: dimension = 3
        integer(i8) :: n_steps = -1
        real(dp) :: run_time = -1.0_dp
        integer(i8) :: seed = 12345
        real(dp) :: walltime_limit = -1.0_dp        !< seconds; stop with a checkpoint before it (<= 0: none)
        ! &system
        character(len=path_max) :: read_data = ''
        character(len=path_max) :: atoms_file = ''
        character(len=path_max) :: read_h5md = ''
        integer(i8) :: h5md_frame = -1              !< frame of read_h5md (1 = first, -1 = last)
        character(len=path_max) :: read_checkpoint = ''  !< continue the run from this checkpoint
        !> a restart's thermo CSV and trajectory: 'append' (cut back to the checkpoint and continued)
        !> or 'new' (new files <stem>.partN<ext>, the earlier ones left as they are)
        character(len=16) :: restart_outputs = 'append'
        character(len=8) :: lattice = ''
        real(dp) :: lattice_constant = -1.0_dp
        real(dp) :: density = -1.0_dp
        integer :: cells(3) = 0
        logical :: periodic(3) = .true.
        real(dp) :: box_lo(3) = unset, box_hi(3) = unset
        real(dp) :: mass(max_types) = -1.0_dp
        real(dp) :: temperature = -1.0_dp
        logical :: reverse_velocities = .false.
        character(len=path_max) :: mesh_file = ''    !< Gmsh MSH mesh: nodes are atoms, tetrahedra elements
        real(dp) :: mass_density = -1.0_dp          !< mesh: lumped nodal masses rho V0 / 4 per element
        real(dp) :: body_velocity(3, max_bodies) = 0, body_angular_velocity(3, max_bodies) = 0  !< per body
        real(dp) :: lambda = unset, mu = unset      !< neohookean: Lame constants
        !> neohookean: the Lame constants of the elements of Gmsh volume entity v (unset: lambda, mu)
        real(dp) :: volume_lambda(max_volumes) = unset, volume_mu(max_volumes) = unset
        real(dp) :: contact_stiffness = unset, contact_distance = unset  !< contact between mesh bodies (N/m, m)
        character(len=16) :: contact_model = 'node_face'                 !< 'node_face' or 'node_node'
        !> rigid walls for a mesh's boundary nodes: 'none', 'box' (the box's six faces) or 'planes'
        character(len=16) :: walls = 'none'
        real(dp) :: wall_planes(6, max_walls) = unset   !< walls = 'planes': a point and a normal per plane
        integer :: nwall_planes = 0                     !< planes given in wall_planes
        real(dp) :: wall_stiffness = unset, wall_distance = unset   !< the walls' barrier (N/m, m)
        ! &potential
        character(len=24) :: potential = default_potential_style
        type(potential_style_t) :: pot_style = potential_style_t()   !< what the style is and takes (set with it)
        character(len=path_max) :: potential_file = ''   !< EAM: the LAMMPS potential file
        character(len=8) :: elements(max_types) = ''  !< eam/alloy, eam/fs: element of each atom type
        real(dp) :: epsilon(max_types, max_types) = unset
        real(dp) :: sigma(max_types, max_types) = unset
        real(dp) :: cutoff = -1.0_dp                !< 0: no cutoff (non-periodic scenes only)
        real(dp) :: pair_cutoff(max_types, max_types) = unset
        logical :: shift = .false.
        character(len=8) :: precision = 'double'    !< LJ pair arithmetic: 'double' or 'mixed' (single pairs, double sums)
        !> hard_sphere, square_well: per type pair hard-core diameter, well depth and outer radius
        !> (well_radius, or well_lambda times the diameter)
        real(dp) :: diameter(max_types, max_types) = unset
        real(dp) :: well_depth(max_types, max_types) = unset
        real(dp) :: well_lambda(max_types, max_types) = unset
        real(dp) :: well_radius(max_types, max_types) = unset
        ! &integrator
        character(len=24) :: integrator = default_integrator_style
        type(integrator_style_t) :: integ_style = integrator_style_t()   !< how it integrates (set with it)
        real(dp) :: dt = -1.0_dp
        real(dp) :: terrace_height = -1.0_dp        !< energy stepping: h (energy)
        real(dp) :: target_mean_dt = -1.0_dp        !< energy stepping: pick h for this mean event interval
        real(dp) :: root_tolerance = 1.0e-9_dp      !< energy stepping: |V - level| <= tol * h at a kick
        ! &neighbor
        real(dp) :: skin = -1.0_dp
        character(len=16) :: list = 'auto'
        !> 'auto': on one rank, a pass that can reads the periodic images as their owners between
        !> builds (terrace_scene_planner: wrap_images); 'copies': the images always copied
        character(len=16) :: images = 'auto'
        integer :: list_every = 1                   !< steps between list checks (check) or rebuilds (no check)
        logical :: list_check = .true.              !< rebuild only when an atom has moved skin/2
        real(dp) :: buffer_tolerance = -1.0_dp      !< > 0: skin from this energy drift per atom per time
        real(dp) :: buffer_drift = -1.0_dp          !< (set with the scene) the skin's estimated drift
        real(dp) :: buffer_temperature = -1.0_dp    !< (set with the scene) the estimate's temperature
        !> > 0: velocity Verlet builds the list with this skin and prunes the force pass's list from it
        !> (pairs within cutoff + skin) when an atom has moved skin/2 (0: off)
        real(dp) :: outer_skin = 0
        !> > 0: with a fixed schedule (every, check = .false., or buffer_tolerance) the outer list's prunes
        !> come every this many steps instead (0: off)
        integer :: prune_every = 0
        ! &output
        integer(i8) :: thermo_every = -1
        real(dp) :: thermo_interval = -1.0_dp
        character(len=path_max) :: thermo_file = ''
        character(len=path_max) :: forces_file = ''
        character(len=path_max) :: final_atoms_file = ''
        character(len=path_max) :: trajectory_file = ''
        integer(i8) :: trajectory_every = -1
        real(dp) :: trajectory_interval = -1.0_dp
        character(len=64) :: trajectory_fields = 'position velocity image'
        logical :: overwrite = .false.
        character(len=path_max) :: checkpoint_file = ''
        character(len=path_max) :: summary_file = ''   !< JSON run summary ('': none)
        real(dp) :: progress_seconds = 60.0_dp          !< wall seconds without a screen line before a progress line
        real(dp) :: checkpoint_interval = -1.0_dp   !< time between checkpoints
        integer(i8) :: checkpoint_every = -1        !< steps between checkpoints (velocity Verlet)
        ! &thermostat
        character(len=16) :: thermostat = 'none'    !< none, langevin, csvr, nose_hoover, andersen
        real(dp) :: thermostat_temperature = -1.0_dp      !< target at time 0
        real(dp) :: thermostat_temperature_end = -1.0_dp  !< target at the end (linear ramp); < 0: no ramp
        real(dp) :: thermostat_damping = -1.0_dp          !< relaxation time
        real(dp) :: thermostat_interval = -1.0_dp         !< energy stepping CSVR: time between rescalings
        integer :: chain_length = 3                       !< Nose-Hoover chain length
        integer(i8) :: thermostat_seed = -1               !< < 0: &run seed
        logical :: zero_momentum = .false.
        ! &barostat
        character(len=16) :: barostat = 'none'      !< none, c_rescale, mc
        real(dp) :: barostat_pressure = 0           !< target pressure (the run's pressure unit)
        real(dp) :: barostat_damping = -1.0_dp      !< C-rescale: relaxation time tau_p
        real(dp) :: barostat_compressibility = -1.0_dp  !< C-rescale: isothermal compressibility (1/pressure)
        character(len=8) :: barostat_couple = 'iso'
        real(dp) :: barostat_interval = -1.0_dp     !< energy stepping mc: time between volume moves
        ! &minimize
        character(len=8) :: minimize = ''           !< '' (none), fire, cg
        real(dp) :: etol = 0, ftol = 0              !< LAMMPS minimize's stopping tolerances
        integer(i8) :: max_iterations = 10000, max_evaluations = 100000
        character(len=8) :: box_relax = 'none'      !< none; iso, aniso: the box relaxed too
        real(dp) :: min_pressure = 0                !< box_relax: target pressure
    contains
        procedure :: where => cfg_where
        procedure :: scene_source => cfg_scene_source
    end type config_t

    public :: read_config, is_unset

    character(len=*), parameter :: groups_allowed = 'run, system, potential, integrator, neighbor, output, thermostat, '// &
                                                    'barostat, minimize'

    !> Walks the assignments of one namelist group: the current item, its key's kind, its text.
    type :: item_reader_t
        integer :: k = 0, ios = 0
        character(len=:), allocatable :: kind, buf
        character(len=256) :: msg = ''
    contains
        procedure :: next => reader_next
        procedure :: done => reader_done
    end type item_reader_t

contains

    elemental logical function is_unset(x)
        real(dp), intent(in) :: x
        is_unset = x == unset
    end function is_unset

    function cfg_where(self, group, key) result(s)
        class(config_t), intent(in) :: self
        character(len=*), intent(in) :: group, key
        character(len=:), allocatable :: s
        s = self%nml%where(group, key)
    end function cfg_where

    !> 'file: &system: key' for the input the atoms come from (for messages about the scene).
    function cfg_scene_source(self) result(s)
        class(config_t), intent(in) :: self
        character(len=:), allocatable :: s
        if (len_trim(self%read_h5md) > 0) then
            s = trim(self%read_h5md)//': &system: read_h5md'
        else if (len_trim(self%read_data) > 0) then
            s = trim(self%read_data)//': &system: read_data'
        else if (len_trim(self%atoms_file) > 0) then
            s = trim(self%atoms_file)//': &system: atoms_file'
        else if (len_trim(self%mesh_file) > 0) then
            s = trim(self%mesh_file)//': &system: mesh_file'
        else
            s = self%path//': &system: lattice'
        end if
    end function cfg_scene_source

    !> Read the file on rank 0, broadcast it, parse and validate on every rank (collective).
    subroutine read_config(path, cfg)
        character(len=*), intent(in) :: path
        type(config_t), intent(out) :: cfg
        character(len=:), allocatable :: text
        integer :: i

        cfg%path = path
        call read_input_text(path, text)
        if (len_trim(text) == 0) call stop_all(path//': the input file is empty (expected namelist groups &run, &system, ...)')

        call parse_namelist_text(text, path, cfg%nml)
        if (len(cfg%nml%syntax_error) > 0) call stop_all(cfg%nml%syntax_error)
        do i = 1, cfg%nml%ngroups
            select case (cfg%nml%groups(i))
            case ('run', 'system', 'potential', 'integrator', 'neighbor', 'output', 'thermostat', 'barostat', 'minimize')
                if (count(cfg%nml%groups(1:i - 1) == cfg%nml%groups(i)) > 0) &
                    call stop_all(at_line(cfg%path, cfg%nml%group_lines(i))//'&'//trim(cfg%nml%groups(i))// &
                                  ': group given twice (merge its keys into one group)')
            case default
                call stop_all(at_line(cfg%path, cfg%nml%group_lines(i))//'&'//trim(cfg%nml%groups(i))// &
                              ': unknown namelist group (allowed: '//groups_allowed//')')
            end select
        end do
        call read_run(cfg)
        call read_system(cfg)
        call read_potential(cfg)
        call read_integrator(cfg)
        call read_neighbor(cfg)
        call read_output(cfg)
        call read_thermostat(cfg)
        call read_barostat(cfg)
        call read_minimize(cfg)
        call validate(cfg)
        call check_input_files(cfg)
    end subroutine read_config

    !> Every input file the deck names must exist and be a regular file (checked on rank 0, before
    !> anything is read). File names are taken from the working directory, as LAMMPS and GROMACS
    !> do; the error shows the absolute path tried and whether the file is next to the deck.
    subroutine check_input_files(cfg)
        use terrace_errors, only: check_all
        type(config_t), intent(in) :: cfg
        character(len=:), allocatable :: msg
        msg = ''
        if (world%rank == 0) then
            call one('system', 'read_data', cfg%read_data)
            call one('system', 'atoms_file', cfg%atoms_file)
            call one('system', 'read_h5md', cfg%read_h5md)
            call one('system', 'read_checkpoint', cfg%read_checkpoint)
            call one('system', 'mesh_file', cfg%mesh_file)
            call one('potential', 'file', cfg%potential_file)
        end if
        call check_all(len(msg) == 0, msg)
    contains
        subroutine one(group, key, path)
            character(len=*), intent(in) :: group, key, path
            character(len=:), allocatable :: abs_path, beside
            logical :: ok
            if (len(msg) > 0 .or. len_trim(path) == 0) return
            select case (path_kind(path))
            case (path_regular)
                return
            case (path_directory)
                msg = cfg%where(group, key)//" = '"//trim(path)//"': cannot open: it is a directory"
            case (path_special)
                msg = cfg%where(group, key)//" = '"//trim(path)//"': cannot open: not a regular file "// &
                      '(a device, pipe or socket)'
            case default
                abs_path = resolve_path(path, ok)
                msg = cfg%where(group, key)//" = '"//trim(path)//"': cannot open: no such file (looked for "// &
                      abs_path//')'
                if (path(1:1) /= '/' .and. directory_of(cfg%path) /= '.') then
                    beside = directory_of(cfg%path)//'/'//trim(path)
                    if (path_kind(beside) == path_regular) msg = msg//'; a file of that name is next to the deck, '// &
                        beside//' (file names are relative to the working directory, not to the deck)'
                end if
            end select
        end subroutine one
    end subroutine check_input_files


    !> The next assignment of group after the current item: its key checked against allowed, its
    !> type description in kind and its text for a namelist read in buf; .false. when none is left.
    logical function reader_next(self, cfg, group, allowed) result(found)
        class(item_reader_t), intent(inout) :: self
        type(config_t), intent(in) :: cfg
        character(len=*), intent(in) :: group, allowed(:)
        found = .false.
        do while (self%k < cfg%nml%count)
            self%k = self%k + 1
            if (cfg%nml%items(self%k)%group /= group) cycle
            self%kind = check_key(cfg, self%k, allowed)
            self%buf = item_text(cfg, self%k, group)
            found = .true.
            return
        end do
    end function reader_next

    !> After the namelist read of the current item: a read error, or a value text that does not fit
    !> the key's kind (unless check_text is .false.), stops the run.
    subroutine reader_done(self, cfg, check_text)
        class(item_reader_t), intent(in) :: self
        type(config_t), intent(in) :: cfg
        logical, intent(in), optional :: check_text
        if (self%ios /= 0) call bad_value(cfg, self%k, self%kind, self%msg)
        if (present(check_text)) then
            if (.not. check_text) return
        end if
        call check_value_text(cfg, self%k, self%kind)
    end subroutine reader_done

    !> Key k must be one of `allowed` ("name:type" entries); returns the type description.
    function check_key(cfg, k, allowed) result(kind)
        type(config_t), intent(in) :: cfg
        integer, intent(in) :: k
        character(len=*), intent(in) :: allowed(:)
        character(len=:), allocatable :: kind, names
        integer :: i, p
        do i = 1, size(allowed)
            p = index(allowed(i), ':')
            if (allowed(i)(1:p - 1) == cfg%nml%items(k)%key) then
                kind = trim(allowed(i)(p + 1:))
                return
            end if
        end do
        names = ''
        do i = 1, size(allowed)
            p = index(allowed(i), ':')
            names = names//allowed(i)(1:p - 1)
            if (i < size(allowed)) names = names//', '
        end do
        call stop_all(at_line(cfg%path, cfg%nml%items(k)%line)//'&'//trim(cfg%nml%items(k)%group)//': '// &
                      trim(cfg%nml%items(k)%key)//': unknown key (allowed: '//names//')')
    end function check_key

    !> Checks on the text of one assignment, made where it is read, for every key alike (so that no
    !> key can slip through a later `x <= 0` test, which NaN passes):
    !>  - a real-valued key: every number is finite, zero or of magnitude in [1e-30, real_limit(key)];
    !>  - a file name: at most path_max characters (never truncated);
    !>  - a one-word string (units, lattice, style, list, elements): one word that fits its variable.
    subroutine check_value_text(cfg, k, kind)
        use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
        type(config_t), intent(in) :: cfg
        integer, intent(in) :: k
        character(len=*), intent(in) :: kind
        character(len=:), allocatable :: v, tok, key, head
        character(len=32) :: lim
        real(dp) :: x
        integer :: i, j, ios, star, width
        key = trim(cfg%nml%items(k)%key)
        v = cfg%nml%items(k)%value
        head = at_line(cfg%path, cfg%nml%items(k)%line)//'&'//trim(cfg%nml%items(k)%group)//': '// &
               cfg%nml%items(k)%target//' = '
        if (index(kind, 'real') > 0) then
            write (lim, '(es8.1)') real_limit(key)
            i = 1
            do while (i <= len(v))
                if (index(', '//achar(9)//achar(10)//achar(13), v(i:i)) > 0) then
                    i = i + 1; cycle
                end if
                j = i
                do while (j <= len(v))
                    if (index(', '//achar(9)//achar(10)//achar(13), v(j:j)) > 0) exit
                    j = j + 1
                end do
                tok = v(i:j - 1)
                i = j
                star = index(tok, '*')          ! r*value: a repeat count
                if (star > 0) tok = tok(star + 1:)
                if (len(tok) == 0) cycle
                read (tok, *, iostat=ios) x
                if (ios /= 0) cycle
                if (.not. ieee_is_finite(x)) call stop_all(head//tok//': not a finite number (NaN and '// &
                    'Infinity are not allowed, and a number beyond 1.8e308 reads as Infinity)')
                if (abs(x) > real_limit(key)) call stop_all(head//tok//': out of range (allowed: |'//key// &
                    '| <= '//trim(adjustl(lim))//' in any units)')
                if (x /= 0 .and. abs(x) < 1.0e-30_dp) call stop_all(head//tok//': out of range (allowed: 0 '// &
                    'or a magnitude of at least 1e-30)')
            end do
        else if (index(kind, 'file name') > 0) then
            if (len(v) - 2 > path_max) then
                write (lim, '(i0)') len(v) - 2
                call stop_all(head//"'"//v(2:min(len(v), 60))//"...': the file name has "//trim(lim)// &
                              ' characters (the most a path may have is 4096)')
            end if
        else
            width = 0
            select case (key)
            case ('units', 'list')
                width = 16
            case ('lattice', 'elements')
                width = 8
            case ('style')
                width = 24
            end select
            if (width == 0) return
            ! each quoted word (elements has several)
            i = 1
            do while (i <= len(v))
                if (v(i:i) /= "'" .and. v(i:i) /= '"') then
                    i = i + 1; cycle
                end if
                j = index(v(i + 1:), v(i:i))
                if (j == 0) return                ! the typed read reports it
                tok = v(i + 1:i + j - 1)
                i = i + j + 1
                if (len_trim(adjustl(tok)) > width .or. index(trim(adjustl(tok)), ' ') > 0) &
                    call stop_all(head//v//": '"//tok//"' is not one word of at most "// &
                                  trim(int_text(width))//' characters')
            end do
        end if
    end subroutine check_value_text

    !> Largest magnitude a real key may take, in any units: beyond it no run makes sense and the
    !> products the engine forms (k_B T / m, box volumes, run_time / dt) would lose meaning.
    pure real(dp) function real_limit(key)
        character(len=*), intent(in) :: key
        select case (key)
        case ('temperature', 'epsilon', 'mass', 'terrace_height', 'walltime_limit')
            real_limit = 1.0e9_dp
        case ('run_time', 'thermo_interval', 'trajectory_interval', 'checkpoint_interval')
            real_limit = 1.0e12_dp
        case ('lambda', 'mu', 'volume_lambda', 'volume_mu', 'contact_stiffness', 'wall_stiffness')   ! Pa; N/m: up to diamond's moduli with room
            real_limit = 1.0e13_dp
        case default            ! lengths, densities, dt, target_mean_dt, root_tolerance
            real_limit = 1.0e6_dp
        end select
    end function real_limit


    subroutine bad_value(cfg, k, kind, msg)
        type(config_t), intent(in) :: cfg
        integer, intent(in) :: k
        character(len=*), intent(in) :: kind, msg
        call stop_all(at_line(cfg%path, cfg%nml%items(k)%line)//'&'//trim(cfg%nml%items(k)%group)//': '// &
                      cfg%nml%items(k)%target//' = '//cfg%nml%items(k)%value//': cannot read the value (expected '// &
                      kind//'; '//trim(msg)//')')
    end subroutine bad_value

    function item_text(cfg, k, group) result(s)
        type(config_t), intent(in) :: cfg
        integer, intent(in) :: k
        character(len=*), intent(in) :: group
        character(len=:), allocatable :: s
        s = '&'//group//' '//cfg%nml%items(k)%target//' = '//cfg%nml%items(k)%value//' /'
    end function item_text

    subroutine read_run(cfg)
        type(config_t), intent(inout) :: cfg
        character(len=16) :: units
        integer :: dimension
        integer(i8) :: n_steps, seed
        real(dp) :: run_time, walltime_limit
        namelist /run/ units, dimension, n_steps, run_time, seed, walltime_limit
        character(len=*), parameter :: keys(6) = [character(len=40) :: 'units:a quoted string', &
            'dimension:an integer', 'n_steps:an integer', 'run_time:a real number', 'seed:an integer', &
            'walltime_limit:a real number (seconds)']
        type(item_reader_t) :: it
        logical :: ok
        units = 'metal'; dimension = 3; n_steps = -1; run_time = -1.0_dp; seed = 12345; walltime_limit = -1.0_dp
        do while (it%next(cfg, 'run', keys))
            read (it%buf, nml=run, iostat=it%ios, iomsg=it%msg)
            call it%done(cfg)
        end do
        cfg%units = make_units(lower(trim(units)), ok)
        if (.not. ok) call stop_all(cfg%where('run', 'units')//" = '"//trim(units)//"': unsupported units (allowed: "// &
                                    unit_names_allowed//')')
        cfg%dimension = dimension
        cfg%n_steps = n_steps
        cfg%run_time = run_time
        cfg%seed = seed
        cfg%walltime_limit = walltime_limit
    end subroutine read_run

    subroutine read_system(cfg)
        type(config_t), intent(inout) :: cfg
        character(len=path_max) :: read_data, atoms_file, read_h5md, read_checkpoint
        character(len=16) :: restart_outputs
        integer(i8) :: h5md_frame
        character(len=8) :: lattice
        real(dp) :: lattice_constant, density, box_lo(3), box_hi(3), mass(max_types), temperature
        integer :: cells(3)
        logical :: periodic(3), reverse_velocities
        character(len=path_max) :: mesh_file
        real(dp) :: mass_density, velocity(3, max_bodies), angular_velocity(3, max_bodies)
        namelist /system/ read_data, atoms_file, lattice, lattice_constant, density, cells, periodic, &
            box_lo, box_hi, mass, temperature, reverse_velocities, read_h5md, h5md_frame, read_checkpoint, &
            restart_outputs, mesh_file, mass_density, velocity, angular_velocity
        character(len=*), parameter :: keys(20) = [character(len=60) :: 'read_data:a quoted file name', &
            'mesh_file:a quoted file name', 'mass_density:a real number', &
            'velocity:three reals per body (velocity(:,2) = ...)', &
            'angular_velocity:three reals per body', &
            'read_checkpoint:a quoted file name', &
            "restart_outputs:a quoted string ('append' or 'new')", &
            'read_h5md:a quoted file name', 'h5md_frame:an integer (1 = first, -1 = last)', &
            'reverse_velocities:a logical', &
            'atoms_file:a quoted file name', 'lattice:a quoted string', 'lattice_constant:a real number', &
            'density:a real number', 'cells:three integers', 'periodic:three logicals (.true./.false.)', &
            'box_lo:three real numbers', 'box_hi:three real numbers', 'mass:real numbers, one per atom type', &
            'temperature:a real number']
        type(item_reader_t) :: it
        read_data = ''; atoms_file = ''; lattice = ''; lattice_constant = -1; density = -1
        read_h5md = ''; h5md_frame = -1; read_checkpoint = ''; restart_outputs = 'append'
        cells = 0; periodic = .true.; box_lo = unset; box_hi = unset; mass = -1; temperature = -1
        reverse_velocities = .false.
        mesh_file = ''; mass_density = -1; velocity = 0; angular_velocity = 0
        do while (it%next(cfg, 'system', keys))
            read (it%buf, nml=system, iostat=it%ios, iomsg=it%msg)
            call it%done(cfg)
        end do
        cfg%read_data = read_data; cfg%atoms_file = atoms_file; cfg%lattice = lower(lattice)
        cfg%read_h5md = read_h5md; cfg%h5md_frame = h5md_frame; cfg%read_checkpoint = read_checkpoint
        cfg%restart_outputs = lower(restart_outputs)
        cfg%lattice_constant = lattice_constant; cfg%density = density; cfg%cells = cells
        cfg%periodic = periodic; cfg%box_lo = box_lo; cfg%box_hi = box_hi; cfg%mass = mass
        cfg%temperature = temperature
        cfg%reverse_velocities = reverse_velocities
        cfg%mesh_file = mesh_file; cfg%mass_density = mass_density
        cfg%body_velocity = velocity; cfg%body_angular_velocity = angular_velocity
    end subroutine read_system

    subroutine read_potential(cfg)
        type(config_t), intent(inout) :: cfg
        character(len=24) :: style
        character(len=path_max) :: file
        character(len=8) :: elements(max_types)
        real(dp) :: epsilon(max_types, max_types), sigma(max_types, max_types), cutoff
        real(dp) :: pair_cutoff(max_types, max_types)
        logical :: shift
        real(dp) :: lambda, mu, contact_stiffness, contact_distance
        character(len=16) :: contact_model, walls
        real(dp) :: wall_planes(6, max_walls), wall_stiffness, wall_distance
        real(dp) :: volume_lambda(max_volumes), volume_mu(max_volumes)
        character(len=8) :: precision
        real(dp), dimension(max_types, max_types) :: diameter, well_depth, well_lambda, well_radius
        namelist /potential/ style, epsilon, sigma, cutoff, pair_cutoff, shift, file, elements, lambda, mu, &
            contact_stiffness, contact_distance, contact_model, precision, diameter, well_depth, well_lambda, well_radius, &
            walls, wall_planes, wall_stiffness, wall_distance, volume_lambda, volume_mu
        character(len=*), parameter :: keys(24) = [character(len=60) :: 'style:a quoted string', &
            'diameter:a real number (or diameter(i,j) = ...)', 'well_depth:a real number (or well_depth(i,j) = ...)', &
            'well_lambda:a real number (or well_lambda(i,j) = ...)', &
            'well_radius:a real number (or well_radius(i,j) = ...)', &
            'lambda:a real number (Pa)', 'mu:a real number (Pa)', &
            'volume_lambda:volume_lambda(v) = a real (Pa), v = 1..64', &
            'volume_mu:volume_mu(v) = a real (Pa), v = 1..64', &
            'contact_stiffness:a real number (N/m)', 'contact_distance:a real number (m)', &
            'contact_model:a quoted string', &
            "walls:a quoted string ('none', 'box' or 'planes')", &
            'wall_planes:six reals per plane (point, normal)', &
            'wall_stiffness:a real number (N/m)', 'wall_distance:a real number (m)', &
            'epsilon:a real number (or epsilon(i,j) = ...)', 'sigma:a real number (or sigma(i,j) = ...)', &
            'cutoff:a real number', 'pair_cutoff:pair_cutoff(i,j) = a real number', 'shift:a logical', &
            'precision:a quoted string', 'file:a quoted file name', 'elements:quoted element names, one per atom type']
        type(item_reader_t) :: it
        style = default_potential_style
        epsilon = unset; sigma = unset; cutoff = -1; pair_cutoff = unset; shift = .false.
        file = ''; elements = ''; lambda = unset; mu = unset; contact_stiffness = unset; contact_distance = unset
        volume_lambda = unset; volume_mu = unset
        contact_model = 'node_face'; precision = 'double'
        walls = 'none'; wall_planes = unset; wall_stiffness = unset; wall_distance = unset
        diameter = unset; well_depth = unset; well_lambda = unset; well_radius = unset
        do while (it%next(cfg, 'potential', keys))
            read (it%buf, nml=potential, iostat=it%ios, iomsg=it%msg)
            call it%done(cfg)
        end do
        cfg%potential = lower(style); cfg%pot_style = pots(style_row(pots%name, cfg%potential))
        cfg%epsilon = epsilon; cfg%sigma = sigma; cfg%cutoff = cutoff
        cfg%pair_cutoff = pair_cutoff; cfg%shift = shift
        cfg%potential_file = file; cfg%elements = elements
        cfg%lambda = lambda; cfg%mu = mu
        cfg%volume_lambda = volume_lambda; cfg%volume_mu = volume_mu
        cfg%contact_stiffness = contact_stiffness; cfg%contact_distance = contact_distance
        cfg%contact_model = lower(contact_model)
        cfg%walls = lower(walls); cfg%wall_planes = wall_planes
        cfg%nwall_planes = count(.not. is_unset(wall_planes))
        cfg%wall_stiffness = wall_stiffness; cfg%wall_distance = wall_distance
        cfg%precision = lower(precision)
        cfg%diameter = diameter; cfg%well_depth = well_depth; cfg%well_lambda = well_lambda
        cfg%well_radius = well_radius
    end subroutine read_potential

    subroutine read_integrator(cfg)
        type(config_t), intent(inout) :: cfg
        character(len=24) :: style
        real(dp) :: dt, terrace_height, target_mean_dt, root_tolerance
        namelist /integrator/ style, dt, terrace_height, target_mean_dt, root_tolerance
        character(len=*), parameter :: keys(5) = [character(len=40) :: 'style:a quoted string', 'dt:a real number', &
            'terrace_height:a real number', 'target_mean_dt:a real number', 'root_tolerance:a real number']
        type(item_reader_t) :: it
        style = default_integrator_style; dt = -1; terrace_height = -1; target_mean_dt = -1; root_tolerance = 1.0e-9_dp
        do while (it%next(cfg, 'integrator', keys))
            read (it%buf, nml=integrator, iostat=it%ios, iomsg=it%msg)
            call it%done(cfg)
        end do
        cfg%integrator = lower(style); cfg%integ_style = integs(style_row(integs%name, cfg%integrator)); cfg%dt = dt
        cfg%terrace_height = terrace_height; cfg%target_mean_dt = target_mean_dt; cfg%root_tolerance = root_tolerance
    end subroutine read_integrator

    !> &neighbor buffer_tolerance: the skin from an energy-drift estimate (terrace_verlet_buffer)
    !> for a list rebuilt every `every` steps (default 10) without a check; velocity Verlet, 3-D.
    !> skin and check = .true. are refused with it; which potentials serve the estimate the
    !> potential says itself, with the scene (potential_t%cutoff_derivatives, terrace_scene_builder).
    subroutine check_buffer_tolerance(cfg)
        type(config_t), intent(inout) :: cfg
        character(len=:), allocatable :: at
        at = cfg%where('neighbor', 'buffer_tolerance')
        if (.not. (cfg%buffer_tolerance > 0)) call stop_all(at//': must be > 0 (an energy drift per atom per unit '// &
            'time, '//trim(cfg%units%energy)//' per '//trim(cfg%units%time)//'; GROMACS''s default is 0.005 kJ/mol/ps)')
        if (cfg%nml%find('neighbor', 'skin') > 0) call stop_all(at//': give skin or buffer_tolerance, not both '// &
            '(buffer_tolerance sets the skin)')
        if (cfg%nml%find('neighbor', 'check') > 0 .and. cfg%list_check) call stop_all(at//': the list is rebuilt '// &
            'every `every` steps without a check (allowed with buffer_tolerance: check = .false.; for the exact list, '// &
            'give skin instead)')
        if (cfg%dimension /= 3) call stop_all(at//': the estimate is for 3-D runs (allowed with dimension = 2: skin)')
        cfg%list_check = .false.
        if (cfg%nml%find('neighbor', 'every') == 0) cfg%list_every = 10
    end subroutine check_buffer_tolerance

    subroutine read_neighbor(cfg)
        type(config_t), intent(inout) :: cfg
        real(dp) :: skin, buffer_tolerance, outer_skin
        character(len=16) :: list, images
        integer :: every, prune_every
        logical :: check
        namelist /neighbor/ skin, list, every, check, buffer_tolerance, outer_skin, prune_every, images
        character(len=*), parameter :: keys(8) = [character(len=40) :: 'skin:a real number', 'list:a quoted string', &
                                                  'every:an integer', 'check:a logical', 'buffer_tolerance:a real number', &
                                                  'outer_skin:a real number', 'prune_every:an integer', &
                                                  'images:a quoted string']
        type(item_reader_t) :: it
        skin = -1; list = 'auto'; every = 1; check = .true.; buffer_tolerance = -1; outer_skin = 0; prune_every = 0
        images = 'auto'
        do while (it%next(cfg, 'neighbor', keys))
            read (it%buf, nml=neighbor, iostat=it%ios, iomsg=it%msg)
            call it%done(cfg)
        end do
        cfg%skin = skin; cfg%list = lower(list); cfg%list_every = every; cfg%list_check = check
        cfg%images = lower(images)
        cfg%buffer_tolerance = buffer_tolerance; cfg%outer_skin = outer_skin; cfg%prune_every = prune_every
    end subroutine read_neighbor

    subroutine read_output(cfg)
        type(config_t), intent(inout) :: cfg
        integer(i8) :: thermo_every
        real(dp) :: thermo_interval
        character(len=path_max) :: thermo_file, forces_file, final_atoms_file, trajectory_file
        integer(i8) :: trajectory_every
        real(dp) :: trajectory_interval
        character(len=64) :: trajectory_fields
        logical :: overwrite
        character(len=path_max) :: checkpoint_file
        real(dp) :: checkpoint_interval
        integer(i8) :: checkpoint_every
        character(len=path_max) :: summary_file
        real(dp) :: progress_seconds
        namelist /output/ thermo_every, thermo_interval, thermo_file, forces_file, final_atoms_file, trajectory_file, &
            trajectory_every, trajectory_interval, trajectory_fields, overwrite, checkpoint_file, checkpoint_interval, &
            checkpoint_every, summary_file, progress_seconds
        character(len=*), parameter :: keys(15) = [character(len=72) :: 'thermo_every:an integer', &
            'checkpoint_file:a quoted file name', 'checkpoint_interval:a real number', 'checkpoint_every:an integer', &
            'thermo_interval:a real number', 'thermo_file:a quoted file name', 'forces_file:a quoted file name', &
            'final_atoms_file:a quoted file name', 'trajectory_file:a quoted file name', &
            'trajectory_every:an integer', 'trajectory_interval:a real number', &
            'trajectory_fields:a quoted list of position, velocity, force, image', 'overwrite:a logical', &
            'summary_file:a quoted file name', 'progress_seconds:a real number (wall-clock seconds)']
        type(item_reader_t) :: it
        thermo_every = -1; thermo_interval = -1; thermo_file = ''; forces_file = ''; final_atoms_file = ''
        trajectory_file = ''; trajectory_every = -1; trajectory_interval = -1
        trajectory_fields = 'position velocity image'; overwrite = .false.
        checkpoint_file = ''; checkpoint_interval = -1; checkpoint_every = -1
        summary_file = default_summary_file(cfg%path); progress_seconds = 60.0_dp
        do while (it%next(cfg, 'output', keys))
            read (it%buf, nml=output, iostat=it%ios, iomsg=it%msg)
            call it%done(cfg)
        end do
        cfg%thermo_every = thermo_every; cfg%thermo_interval = thermo_interval
        cfg%thermo_file = thermo_file; cfg%forces_file = forces_file; cfg%final_atoms_file = final_atoms_file
        cfg%trajectory_file = trajectory_file; cfg%trajectory_every = trajectory_every
        cfg%trajectory_interval = trajectory_interval; cfg%trajectory_fields = lower(trajectory_fields)
        cfg%overwrite = overwrite
        cfg%checkpoint_file = checkpoint_file; cfg%checkpoint_interval = checkpoint_interval
        cfg%checkpoint_every = checkpoint_every
        cfg%summary_file = summary_file
        if (.not. progress_seconds >= 0) call stop_all(cfg%where('output', 'progress_seconds')// &
            ': must be >= 0 (wall-clock seconds without a screen line before a progress line; 0: none)')
        cfg%progress_seconds = progress_seconds
    end subroutine read_output

    !> The default &output summary_file: the deck's file name without its directory and its '.nml',
    !> with '.summary.json', in the working directory (run.nml -> run.summary.json).
    function default_summary_file(deck) result(name)
        character(len=*), intent(in) :: deck
        character(len=:), allocatable :: name
        integer :: p, n
        p = index(deck, '/', back=.true.)
        name = deck(p + 1:)
        n = len(name)
        if (n > 4) then
            if (lower(name(n - 3:n)) == '.nml') name = name(1:n - 4)
        end if
        name = name//'.summary.json'
    end function default_summary_file

    subroutine read_thermostat(cfg)
        type(config_t), intent(inout) :: cfg
        character(len=16) :: style
        real(dp) :: temperature, temperature_end, damping
        integer :: chain_length
        integer(i8) :: seed
        logical :: zero_momentum
        real(dp) :: interval
        namelist /thermostat/ style, temperature, temperature_end, damping, chain_length, seed, zero_momentum, interval
        character(len=*), parameter :: keys(8) = [character(len=40) :: 'style:a quoted string', &
            'temperature:a real number', 'temperature_end:a real number', 'damping:a real number', &
            'chain_length:an integer', 'seed:an integer', 'zero_momentum:a logical', 'interval:a real number']
        type(item_reader_t) :: it
        style = 'none'; temperature = -1; temperature_end = -1; damping = -1; chain_length = 3; seed = -1
        zero_momentum = .false.; interval = -1
        do while (it%next(cfg, 'thermostat', keys))
            read (it%buf, nml=thermostat, iostat=it%ios, iomsg=it%msg)
            call it%done(cfg)
        end do
        cfg%thermostat = lower(style)
        cfg%thermostat_temperature = temperature; cfg%thermostat_temperature_end = temperature_end
        cfg%thermostat_damping = damping; cfg%chain_length = chain_length; cfg%thermostat_seed = seed
        cfg%zero_momentum = zero_momentum; cfg%thermostat_interval = interval
    end subroutine read_thermostat

    subroutine read_barostat(cfg)
        type(config_t), intent(inout) :: cfg
        character(len=16) :: style
        character(len=8) :: couple
        real(dp) :: pressure, damping, compressibility, interval
        namelist /barostat/ style, pressure, damping, compressibility, couple, interval
        character(len=*), parameter :: keys(6) = [character(len=40) :: 'style:a quoted string', &
            'pressure:a real number', 'damping:a real number', 'compressibility:a real number', &
            'couple:a quoted string', 'interval:a real number']
        type(item_reader_t) :: it
        style = 'none'; couple = 'iso'; pressure = 0; damping = -1; compressibility = -1; interval = -1
        do while (it%next(cfg, 'barostat', keys))
            read (it%buf, nml=barostat, iostat=it%ios, iomsg=it%msg)
            call it%done(cfg)
        end do
        cfg%barostat = lower(style); cfg%barostat_couple = lower(couple)
        cfg%barostat_pressure = pressure; cfg%barostat_damping = damping
        cfg%barostat_compressibility = compressibility; cfg%barostat_interval = interval
    end subroutine read_barostat

    subroutine read_minimize(cfg)
        type(config_t), intent(inout) :: cfg
        character(len=8) :: style, box_relax
        real(dp) :: etol, ftol, pressure
        integer(i8) :: max_iterations, max_evaluations
        namelist /minimize/ style, etol, ftol, max_iterations, max_evaluations, box_relax, pressure
        character(len=*), parameter :: keys(7) = [character(len=40) :: 'style:a quoted string', &
            'etol:a real number', 'ftol:a real number', 'max_iterations:an integer', 'max_evaluations:an integer', &
            'box_relax:a quoted string', 'pressure:a real number']
        type(item_reader_t) :: it
        style = ''; etol = 0; ftol = 0; max_iterations = 10000; max_evaluations = 100000
        box_relax = 'none'; pressure = 0
        do while (it%next(cfg, 'minimize', keys))
            read (it%buf, nml=minimize, iostat=it%ios, iomsg=it%msg)
            call it%done(cfg)
        end do
        cfg%minimize = lower(style); cfg%etol = etol; cfg%ftol = ftol
        cfg%max_iterations = max_iterations; cfg%max_evaluations = max_evaluations
        cfg%box_relax = lower(box_relax); cfg%min_pressure = pressure
    end subroutine read_minimize

    !> &barostat: the style, its keys, and what it needs (velocity Verlet, a thermostat's
    !> temperature, a periodic box of atoms).
    subroutine validate_barostat(cfg)
        type(config_t), intent(inout) :: cfg
        character(len=*), parameter :: styles = "'none', 'c_rescale', 'mc', 'mttk'"
        character(len=:), allocatable :: style_is
        class(thermostat_t), allocatable :: proto
        logical :: given
        given = cfg%nml%find('barostat', 'style') > 0
        if (.not. given) then
            if (cfg%nml%gives_any('barostat', 'pressure damping compressibility couple interval')) &
                call stop_all(cfg%path//': &barostat: style: missing (allowed: '//styles//')')
            return
        end if
        style_is = cfg%where('barostat', 'style')//" = '"//trim(cfg%barostat)//"'"
        select case (cfg%barostat)
        case ('none')
            return
        case ('c_rescale', 'mc', 'mttk')
        case default
            call stop_all(style_is//': unknown barostat (allowed: '//styles//')')
        end select
        if (len_trim(cfg%mesh_file) > 0) call stop_all(style_is//': a barostat changes the box of a periodic '// &
            'scene of atoms; a mesh (&system mesh_file) has free boundaries and no box to scale')
        if (cfg%integ_style%event_driven) call stop_all(style_is//": not with &integrator style = '"// &
            trim(cfg%integrator)//"' (its box stays fixed; allowed with a barostat: style = "// &
            quoted_list(integs%name, ' or ', .not. integs%event_driven)//')')
        if (.not. cfg%integ_style%time_stepped .and. cfg%barostat /= 'mc') call stop_all(style_is// &
            ': runs with &integrator style = '//quoted_list(integs%name, ' or ', integs%time_stepped)// &
            " only (energy stepping: style = 'mc')")
        if (cfg%nml%find('barostat', 'interval') > 0) then
            if (.not. cfg%integ_style%exact_time) call stop_all(cfg%where('barostat', 'interval')// &
                ': for energy stepping only (velocity Verlet tries a volume move every 25 steps)')
            if (.not. (cfg%barostat_interval > 0)) call stop_all(cfg%where('barostat', 'interval')// &
                ': must be > 0 (a time in '//trim(cfg%units%time)//')')
        else if (cfg%integ_style%exact_time) then
            call stop_all(cfg%path//': &barostat: interval: missing (energy stepping: the time between volume '// &
                          'moves, in '//trim(cfg%units%time)//')')
        end if
        if (cfg%thermostat == 'none') call stop_all(style_is//': needs a thermostat (&thermostat style and '// &
            'temperature): the barostat samples at its temperature')
        if (.not. all(cfg%periodic(1:cfg%dimension))) call stop_all(style_is//': needs a box periodic in every '// &
            'dimension (&system periodic)')
        if (cfg%nml%find('barostat', 'pressure') == 0) call stop_all(cfg%path//': &barostat: pressure: missing '// &
            '(the target pressure in '//trim(cfg%units%pressure)//')')
        select case (cfg%barostat_couple)
        case ('iso', 'aniso')
        case default
            call stop_all(cfg%where('barostat', 'couple')//" = '"//trim(cfg%barostat_couple)// &
                          "': unknown (allowed: 'iso', 'aniso')")
        end select
        if (cfg%barostat == 'mttk') then
            call new_thermostat(cfg%thermostat, thermostat_params_t(), proto)
            if (.not. proto%traits%takes_chain) call stop_all(style_is// &
                ": thermostats its particles with the run's Nose-Hoover chain: &thermostat style = '"// &
                trim(cfg%thermostat)//"' not allowed with it (allowed: "//thermostat_names_with_chain()//')')
        end if
        if (cfg%barostat == 'c_rescale' .or. cfg%barostat == 'mttk') then
            if (cfg%nml%find('barostat', 'damping') == 0) call stop_all(cfg%path//': &barostat: damping: missing '// &
                '(the relaxation time tau_p, a time in '//trim(cfg%units%time)//')')
            if (.not. (cfg%barostat_damping > 0)) call stop_all(cfg%where('barostat', 'damping')// &
                ': must be > 0 (a time in '//trim(cfg%units%time)//')')
        end if
        if (cfg%barostat == 'mttk') then
            if (cfg%nml%find('barostat', 'compressibility') > 0) call stop_all(cfg%where('barostat', &
                'compressibility')//": not used by style 'mttk' (its mass follows from damping and the temperature)")
        else if (cfg%barostat == 'c_rescale') then
            if (cfg%nml%find('barostat', 'compressibility') == 0) call stop_all(cfg%path//': &barostat: '// &
                'compressibility: missing (the isothermal compressibility, in 1/('//trim(cfg%units%pressure)//'))')
            if (.not. (cfg%barostat_compressibility > 0)) call stop_all(cfg%where('barostat', 'compressibility')// &
                ': must be > 0 (in 1/('//trim(cfg%units%pressure)//'))')
        else
            if (cfg%nml%find('barostat', 'damping') > 0) call stop_all(cfg%where('barostat', 'damping')// &
                ": not used by style 'mc' (it adapts its volume moves itself)")
            if (cfg%nml%find('barostat', 'compressibility') > 0) call stop_all(cfg%where('barostat', &
                'compressibility')//": not used by style 'mc'")
        end if
    end subroutine validate_barostat

    !> &minimize: the style and its tolerances and limits.
    subroutine validate_minimize(cfg)
        type(config_t), intent(inout) :: cfg
        logical :: any_key
        character(len=:), allocatable :: allowed
        type(minimize_style_t) :: style
        integer :: k
        any_key = .false.
        do k = 1, cfg%nml%count
            if (cfg%nml%items(k)%group == 'minimize') any_key = any_key .or. &
                any(has_word(mins%keys, cfg%nml%items(k)%key))
        end do
        allowed = quoted_list(mins%name, ', ')
        if (cfg%nml%find('minimize', 'style') == 0) then
            if (any_key) call stop_all(cfg%path//': &minimize: style: missing (allowed: '//allowed//')')
            return
        end if
        style = mins(style_row(mins%name, cfg%minimize))
        if (len_trim(style%name) == 0) call stop_all(cfg%where('minimize', 'style')//" = '"//trim(cfg%minimize)// &
            "': unknown minimizer (allowed: "//allowed//')')
        if (.not. (cfg%etol >= 0)) call stop_all(cfg%where('minimize', 'etol')// &
            ': must be >= 0 (relative change of the energy between iterations)')
        if (.not. (cfg%ftol >= 0)) call stop_all(cfg%where('minimize', 'ftol')// &
            ': must be >= 0 (the 2-norm of the global force vector, in '//trim(cfg%units%energy)//'/'// &
            trim(cfg%units%length)//')')
        if (cfg%pot_style%stepped) call stop_all(cfg%where('minimize', 'style')//": not for &potential style = '"// &
            trim(cfg%potential)//"' (its forces are impulses at the steps: no gradient to follow; allowed with "// &
            'a minimization: style = '//quoted_list(pots%name, ' or ', .not. pots%stepped)//')')
        if (cfg%max_iterations < 1) call stop_all(cfg%where('minimize', 'max_iterations')//': must be >= 1')
        if (cfg%max_evaluations < 1) call stop_all(cfg%where('minimize', 'max_evaluations')//': must be >= 1')
        select case (cfg%box_relax)
        case ('none')
            if (cfg%nml%find('minimize', 'pressure') > 0) call stop_all(cfg%where('minimize', 'pressure')// &
                ": the target pressure of box_relax (give box_relax = 'iso' or 'aniso')")
        case ('iso', 'aniso')
            if (len_trim(cfg%mesh_file) > 0) call stop_all(cfg%where('minimize', 'box_relax')// &
                ': a mesh (&system mesh_file) has free boundaries and no box to relax')
            if (.not. all(cfg%periodic(1:cfg%dimension))) call stop_all(cfg%where('minimize', 'box_relax')// &
                ': needs a box periodic in every dimension (&system periodic)')
        case default
            call stop_all(cfg%where('minimize', 'box_relax')//" = '"//trim(cfg%box_relax)// &
                          "': unknown (allowed: 'none', 'iso', 'aniso')")
        end select
        if (cfg%barostat /= 'none' .and. len_trim(cfg%barostat) > 0 .and. .not. cfg%integ_style%time_stepped) &
            call stop_all(cfg%where('minimize', 'style')//': dynamics after a minimization run with velocity Verlet')
    end subroutine validate_minimize

    !> &thermostat: the style, its keys, and whether it fits the integrator (the style says which of
    !> its keys it takes and whether it can act between energy stepping's events: thermostat_factory).
    subroutine validate_thermostat(cfg)
        type(config_t), intent(inout) :: cfg
        character(len=:), allocatable :: style_is
        class(thermostat_t), allocatable :: proto
        logical :: given
        given = cfg%nml%find('thermostat', 'style') > 0
        if (.not. given) then
            if (cfg%nml%gives_any('thermostat', 'temperature damping temperature_end chain_length seed '// &
                                  'zero_momentum interval')) &
                call stop_all(cfg%path//': &thermostat: style: missing (allowed: '//thermostat_styles()//')')
            return
        end if
        style_is = cfg%where('thermostat', 'style')//" = '"//trim(cfg%thermostat)//"'"
        if (.not. is_thermostat_style(cfg%thermostat)) &
            call stop_all(style_is//': unknown thermostat (allowed: '//thermostat_styles()//')')
        call new_thermostat(cfg%thermostat, thermostat_params_t(), proto)
        if (.not. proto%active()) return
        if (cfg%integ_style%exact_time .and. len_trim(proto%traits%event_note) == 0) &
            call stop_all(style_is//': not available with energy stepping, whose trajectory is straight lines and '// &
                          'jumps between events (allowed there: '//thermostat_styles_for_events()//')')
        if (cfg%nml%find('thermostat', 'temperature') == 0) &
            call stop_all(cfg%path//': &thermostat: temperature: missing (the target temperature in '// &
                          trim(cfg%units%temperature)//')')
        if (.not. (cfg%thermostat_temperature > 0)) &
            call stop_all(cfg%where('thermostat', 'temperature')//': must be > 0 (in '//trim(cfg%units%temperature)//')')
        if (cfg%nml%find('thermostat', 'temperature_end') > 0 .and. cfg%integ_style%exact_time .and. &
            .not. (cfg%run_time > 0)) call stop_all(cfg%where('thermostat', 'temperature_end')// &
            ': a temperature ramp with energy stepping needs &run run_time (the ramp runs over that time)')
        if (cfg%nml%find('thermostat', 'temperature_end') > 0) then
            if (.not. (cfg%thermostat_temperature_end > 0)) call stop_all(cfg%where('thermostat', 'temperature_end')// &
                ': must be > 0 (the target at the end of the run, in '//trim(cfg%units%temperature)//')')
        else
            cfg%thermostat_temperature_end = cfg%thermostat_temperature
        end if
        if (cfg%nml%find('thermostat', 'damping') == 0) &
            call stop_all(cfg%path//': &thermostat: damping: missing (the relaxation time, a time in '// &
                          trim(cfg%units%time)//'; about 100 time steps is usual)')
        if (.not. (cfg%thermostat_damping > 0)) &
            call stop_all(cfg%where('thermostat', 'damping')//': must be > 0 (a time in '//trim(cfg%units%time)//')')
        if (cfg%nml%find('thermostat', 'chain_length') > 0) then
            if (.not. proto%traits%takes_chain) call stop_all(cfg%where('thermostat', 'chain_length')// &
                ': only for '//thermostat_styles_with_chain())
            if (cfg%chain_length < 1 .or. cfg%chain_length > max_chain) call stop_all(cfg%where('thermostat', &
                'chain_length')//': must be between 1 and 100 (3 to 10 is usual)')
        end if
        ! energy stepping: CSVR acts at multiples of interval (default damping/10); Andersen with an
        ! interval is the global variant (every atom at multiples of interval)
        if (cfg%nml%find('thermostat', 'interval') > 0) then
            if (.not. cfg%integ_style%exact_time) call stop_all(cfg%where('thermostat', 'interval')// &
                ': only for energy stepping (the time between scheduled thermostat actions; allowed there: '// &
                thermostat_styles_for_events()//'); velocity Verlet acts at every step')
            if (.not. (cfg%thermostat_interval > 0)) call stop_all(cfg%where('thermostat', 'interval')// &
                ': must be > 0 (a time in '//trim(cfg%units%time)//')')
        else if (cfg%integ_style%exact_time) then
            cfg%thermostat_interval = proto%default_interval(cfg%thermostat_damping)
        end if
        ! with energy stepping the thermostat's actions are calendar entries: at most max_events of them
        ! (per atom, for Andersen's collisions at rate 1/damping) in run_time
        if (cfg%integ_style%exact_time .and. cfg%run_time > 0) then
            if (cfg%thermostat_interval > 0) then     ! (nested: no division by 0, which a Debug build traps)
                if (cfg%run_time/cfg%thermostat_interval > max_events) &
                    call stop_all(cfg%where('thermostat', 'interval')//': more than 1e12 thermostat actions in '// &
                                  'run_time (the run would not finish; allowed: at least '// &
                                  sci_text(cfg%run_time/max_events)//' '//trim(cfg%units%time)//' for this run_time)')
            end if
            if (cfg%run_time/cfg%thermostat_damping > max_events) &
                call stop_all(cfg%where('thermostat', 'damping')//': more than 1e12 thermostat events per atom in '// &
                              'run_time (the run would not finish; allowed: at least '// &
                              sci_text(cfg%run_time/max_events)//' '//trim(cfg%units%time)//' for this run_time)')
        end if
        if (cfg%nml%find('thermostat', 'seed') > 0) then
            if (cfg%thermostat_seed <= 0) call stop_all(cfg%where('thermostat', 'seed')//': must be a positive integer')
        else
            cfg%thermostat_seed = cfg%seed
        end if
    end subroutine validate_thermostat

    !> Checks that need no atoms. Checks that need the atoms (overlaps, atoms outside the box,
    !> cutoff against the box) are made when the system is built.
    subroutine validate(cfg)
        type(config_t), intent(inout) :: cfg
        integer :: nsrc
        character(len=32) :: s
        if (cfg%dimension /= 2 .and. cfg%dimension /= 3) then
            write (s, '(i0)') cfg%dimension
            call stop_all(cfg%where('run', 'dimension')//' = '//trim(s)//': unsupported (allowed: 2, 3)')
        end if
        if (cfg%n_steps >= 0 .and. cfg%run_time >= 0) &
            call stop_all(cfg%where('run', 'run_time')//': give either n_steps or run_time, not both')
        if (cfg%nml%find('run', 'n_steps') > 0 .and. cfg%n_steps < 0) &
            call stop_all(cfg%where('run', 'n_steps')//': must be >= 0')
        if (cfg%nml%find('run', 'run_time') > 0 .and. cfg%run_time <= 0) &
            call stop_all(cfg%where('run', 'run_time')//': must be > 0 (a time in '//trim(cfg%units%time)//')')
        if (cfg%n_steps < 0 .and. cfg%run_time < 0) &
            call stop_all(cfg%path//': &run: n_steps: missing (give n_steps, or run_time in '//trim(cfg%units%time)//')')
        if (cfg%seed <= 0) call stop_all(cfg%where('run', 'seed')//': must be a positive integer')

        nsrc = count([len_trim(cfg%read_data) > 0, len_trim(cfg%lattice) > 0, len_trim(cfg%read_h5md) > 0, &
                      len_trim(cfg%mesh_file) > 0 .or. len_trim(cfg%atoms_file) > 0])
        if (nsrc == 0) call stop_all(cfg%path//': &system: read_data: missing (give read_data, lattice, atoms_file, '// &
                                     'read_h5md or mesh_file)')
        if (nsrc > 1) then
            if (len_trim(cfg%mesh_file) > 0) call stop_all(cfg%where('system', 'mesh_file')//': a mesh is its own '// &
                'scene: give no read_data, lattice or read_h5md with it (atoms_file may give current positions)')
            call stop_all(cfg%path//': &system: read_data: give only one of read_data, lattice, atoms_file, read_h5md')
        end if
        if (len_trim(cfg%mesh_file) > 0) call validate_mesh(cfg)
        if (cfg%h5md_frame == 0) call stop_all(cfg%where('system', 'h5md_frame')//': 1 is the first frame, -1 the last')
        if (len_trim(cfg%lattice) > 0) then
            select case (cfg%lattice)
            case ('fcc', 'bcc', 'sc')
                if (cfg%dimension /= 3) call stop_all(cfg%where('system', 'lattice')//" = '"//trim(cfg%lattice)// &
                    "': a 3-D lattice in a 2-D run (allowed in 2-D: 'hex', 'sq')")
            case ('hex', 'sq')
                if (cfg%dimension /= 2) call stop_all(cfg%where('system', 'lattice')//" = '"//trim(cfg%lattice)// &
                    "': a 2-D lattice in a 3-D run (allowed in 3-D: 'fcc', 'bcc', 'sc')")
            case default
                call stop_all(cfg%where('system', 'lattice')//" = '"//trim(cfg%lattice)// &
                              "': unknown lattice (allowed: 'fcc', 'bcc', 'sc', 'hex', 'sq')")
            end select
            if ((cfg%lattice_constant > 0) .eqv. (cfg%density > 0)) &
                call stop_all(cfg%where('system', 'lattice_constant')// &
                              ': give exactly one of lattice_constant and density, and it must be > 0')
            if (any(cfg%cells(1:cfg%dimension) <= 0)) call stop_all(cfg%where('system', 'cells')// &
                ': must be positive integers, one per dimension')
            if (cfg%mass(1) <= 0 .and. .not. cfg%pot_style%needs_file) call stop_all(cfg%where('system', 'mass')// &
                ': missing or <= 0 (mass of type 1 in '//trim(cfg%units%mass)//')')
        end if
        if (cfg%dimension == 2) cfg%periodic(3) = .true.
        if (cfg%nml%find('system', 'temperature') > 0 .and. cfg%temperature < 0) &
            call stop_all(cfg%where('system', 'temperature')//': must be >= 0 (in '//trim(cfg%units%temperature)//')')

        call check_potential_keys(cfg)
        select case (cfg%precision)
        case ('double')
        case ('mixed')
            if (cfg%integ_style%exact_time) call stop_all(cfg%where('potential', 'precision')// &
                " = 'mixed': not available with energy stepping, whose root finding needs double-precision "// &
                "energies and forces (allowed with energy stepping: 'double')")
            if (.not. cfg%pot_style%mixed_precision) call stop_all(cfg%where('potential', 'precision')// &
                " = 'mixed': only for style = "//quoted_list(pots%name, ' or ', pots%mixed_precision)// &
                " (the one-type Lennard-Jones kernel; allowed for style = '"//trim(cfg%potential)//"': 'double')")
        case default
            call stop_all(cfg%where('potential', 'precision')//" = '"//trim(cfg%precision)// &
                          "': unknown precision (allowed: 'double', 'mixed')")
        end select
        if (len_trim(cfg%pot_style%name) == 0) then
            call stop_all(cfg%where('potential', 'style')//" = '"//trim(cfg%potential)// &
                          "': unknown potential (allowed: "//quoted_list(pots%name, ', ')//')')
        else if (cfg%pot_style%needs_file) then
            call validate_eam(cfg)
        else if (cfg%pot_style%mesh) then
            if (len_trim(cfg%mesh_file) == 0) call stop_all(cfg%where('potential', 'style')//" = '"// &
                trim(cfg%potential)//"': needs a mesh (&system mesh_file, a Gmsh MSH file of tetrahedra)")
            call validate_run_settings(cfg)
        else if (cfg%pot_style%stepped) then
            call validate_stepped(cfg)
        else
            call validate_lj(cfg)
        end if
    end subroutine validate

    !> &potential keys of one style given to a style that does not take them (contact: a mesh's).
    subroutine check_potential_keys(cfg)
        type(config_t), intent(in) :: cfg
        character(len=*), parameter :: contact_keys(3) = [character(len=20) :: 'contact_stiffness', &
                                                          'contact_distance', 'contact_model']
        character(len=*), parameter :: wall_keys(4) = [character(len=20) :: 'walls', 'wall_planes', &
                                                       'wall_stiffness', 'wall_distance']
        character(len=*), parameter :: material_keys(2) = [character(len=20) :: 'volume_lambda', 'volume_mu']
        call refuse_keys(cfg, contact_keys, 'contact is between the bodies of a mesh')
        call refuse_keys(cfg, wall_keys, 'walls hold the boundary nodes of a mesh')
        call refuse_keys(cfg, material_keys, 'a material of a mesh''s volume')
    end subroutine check_potential_keys

    !> The first of keys given in &potential whose style does not take it: refused with what the key
    !> is for (what) and the styles that take it.
    subroutine refuse_keys(cfg, keys, what)
        type(config_t), intent(in) :: cfg
        character(len=*), intent(in) :: keys(:), what
        integer :: k
        do k = 1, size(keys)
            if (cfg%nml%find('potential', trim(keys(k))) > 0 .and. &
                .not. has_word(cfg%pot_style%keys, keys(k))) call stop_all(cfg%where('potential', &
                trim(keys(k)))//': '//what//' (style = '// &
                quoted_list(pots%name, ' or ', has_word(pots%keys, keys(k)))//')')
        end do
    end subroutine refuse_keys

    !> The materials of volume entities: volume_lambda(v) and volume_mu(v) given together, mu > 0,
    !> lambda >= 0. (Whether the mesh has volume v is checked when it is read.)
    subroutine validate_volume_materials(cfg)
        type(config_t), intent(in) :: cfg
        integer :: v
        character(len=16) :: sv
        do v = 1, max_volumes
            write (sv, '(a,i0,a)') '(', v, ')'
            if (is_unset(cfg%volume_lambda(v)) .neqv. is_unset(cfg%volume_mu(v))) call stop_all(cfg%where('potential', &
                trim(merge('volume_mu    ', 'volume_lambda', is_unset(cfg%volume_mu(v)))))//trim(sv)// &
                ': missing (give volume_lambda'//trim(sv)//' and volume_mu'//trim(sv)//' together: the Lame '// &
                'constants of the elements of volume '//trim(sv(2:len_trim(sv) - 1))//', in '// &
                trim(cfg%units%pressure)//')')
            if (is_unset(cfg%volume_mu(v))) cycle
            if (.not. (cfg%volume_mu(v) > 0)) call stop_all(cfg%where('potential', 'volume_mu')//trim(sv)// &
                ': must be > 0 (a shear modulus in '//trim(cfg%units%pressure)//')')
            if (cfg%volume_lambda(v) < 0) call stop_all(cfg%where('potential', 'volume_lambda')//trim(sv)// &
                ': must be >= 0 (in '//trim(cfg%units%pressure)//')')
        end do
    end subroutine validate_volume_materials

    !> A mesh scene: the neo-Hookean potential with its Lame constants, a mass density, free boundaries.
    subroutine validate_mesh(cfg)
        type(config_t), intent(inout) :: cfg
        if (.not. cfg%pot_style%mesh) call stop_all(cfg%where('potential', 'style')//" = '"// &
            trim(cfg%potential)//"': a mesh needs style = "//quoted_list(pots%name, ' or ', pots%mesh))
        if (.not. (cfg%mass_density > 0)) call stop_all(cfg%where('system', 'mass_density')//': missing or <= 0 '// &
            '(the solid''s density in '//trim(cfg%units%mass)//'/'//trim(cfg%units%length)//'^3)')
        if (is_unset(cfg%mu)) call stop_all(cfg%path//': &potential: mu: missing (the shear modulus, Lame''s mu, in '// &
                                            trim(cfg%units%pressure)//')')
        if (is_unset(cfg%lambda)) call stop_all(cfg%path//': &potential: lambda: missing (Lame''s first parameter, in '// &
                                                trim(cfg%units%pressure)//')')
        if (.not. (cfg%mu > 0)) call stop_all(cfg%where('potential', 'mu')//': must be > 0 (a shear modulus in '// &
                                              trim(cfg%units%pressure)//')')
        if (cfg%lambda < 0) call stop_all(cfg%where('potential', 'lambda')//': must be >= 0 (in '// &
                                          trim(cfg%units%pressure)//')')
        call validate_volume_materials(cfg)
        if (cfg%nml%find('potential', 'contact_stiffness') > 0 .and. .not. (cfg%contact_stiffness > 0)) &
            call stop_all(cfg%where('potential', 'contact_stiffness')//': must be > 0 (a spring constant in N/m; '// &
                          'leave it out for the default E h_b, h_b the mean boundary edge)')
        if (cfg%nml%find('potential', 'contact_distance') > 0 .and. .not. (cfg%contact_distance > 0)) &
            call stop_all(cfg%where('potential', 'contact_distance')//': must be > 0 (a length in '// &
                          trim(cfg%units%length)//'; leave it out for the default: half the mean boundary edge '// &
                          'for node_face, the mean boundary edge for node_node)')
        select case (cfg%contact_model)
        case ('node_face', 'node_node')
        case default
            call stop_all(cfg%where('potential', 'contact_model')//" = '"//trim(cfg%contact_model)// &
                          "': unknown contact model (allowed: 'node_face' (boundary nodes against the other "// &
                          "body's boundary triangles, the default), 'node_node' (boundary node pairs))")
        end select
        call validate_walls(cfg)
        if (any(cfg%periodic(1:cfg%dimension))) call stop_all(cfg%where('system', 'periodic')// &
            ': a mesh has free boundaries (set periodic = .false., .false., .false.)')
        if (cfg%dimension /= 3) call stop_all(cfg%where('run', 'dimension')//': meshes of tetrahedra are 3-D')
        if (cfg%thermostat /= 'none' .and. len_trim(cfg%thermostat) > 0) call stop_all(cfg%where('thermostat', 'style')// &
            ': thermostats are not available for meshes yet')
        if (cfg%temperature >= 0) call stop_all(cfg%where('system', 'temperature')// &
            ': a mesh starts from its rigid motion (velocity, angular_velocity), not a temperature')
    end subroutine validate_mesh

    !> A mesh's walls: the kind, the planes (six numbers each, a normal of nonzero length), the barrier.
    subroutine validate_walls(cfg)
        type(config_t), intent(inout) :: cfg
        real(dp) :: flat(6*max_walls)
        integer :: w
        select case (cfg%walls)
        case ('none', 'box', 'planes')
        case default
            call stop_all(cfg%where('potential', 'walls')//" = '"//trim(cfg%walls)//"': unknown walls (allowed: "// &
                "'none' (the default), 'box' (the six faces of the box, &system box_lo and box_hi), "// &
                "'planes' (the planes of wall_planes))")
        end select
        if (cfg%walls == 'planes' .and. cfg%nwall_planes == 0) call stop_all(cfg%where('potential', 'walls')// &
            " = 'planes': needs wall_planes (six reals per plane: a point x, y, z, then the normal nx, ny, nz "// &
            'pointing to the side the mesh is on)')
        if (cfg%nwall_planes > 0 .and. cfg%walls /= 'planes') call stop_all(cfg%where('potential', 'wall_planes')// &
            ": only with walls = 'planes' (walls = '"//trim(cfg%walls)//"')")
        if (cfg%nwall_planes > 0) then
            flat = reshape(cfg%wall_planes, [6*max_walls])
            if (mod(cfg%nwall_planes, 6) /= 0 .or. any(is_unset(flat(1:cfg%nwall_planes)))) &
                call stop_all(cfg%where('potential', 'wall_planes')//': '//int_text(cfg%nwall_planes)// &
                ' numbers; allowed: six reals per plane, one plane after the other (a point x, y, z, then the '// &
                'normal nx, ny, nz pointing to the side the mesh is on), at most '//int_text(max_walls)//' planes')
            do w = 1, cfg%nwall_planes/6
                if (.not. (norm2(cfg%wall_planes(4:6, w)) > 0)) call stop_all(cfg%where('potential', 'wall_planes')// &
                    ': plane '//int_text(w)//' has a zero normal (allowed: a normal nx, ny, nz of nonzero length, '// &
                    'pointing to the side the mesh is on)')
            end do
        end if
        if (cfg%walls == 'none') then
            if (cfg%nml%find('potential', 'wall_stiffness') > 0) call stop_all(cfg%where('potential', 'wall_stiffness')// &
                ": only with walls = 'box' or 'planes'")
            if (cfg%nml%find('potential', 'wall_distance') > 0) call stop_all(cfg%where('potential', 'wall_distance')// &
                ": only with walls = 'box' or 'planes'")
        end if
        if (cfg%nml%find('potential', 'wall_stiffness') > 0 .and. .not. (cfg%wall_stiffness > 0)) &
            call stop_all(cfg%where('potential', 'wall_stiffness')//': must be > 0 (a spring constant in N/m; '// &
                          'leave it out for the default E h_b, h_b the mean boundary edge)')
        if (cfg%nml%find('potential', 'wall_distance') > 0 .and. .not. (cfg%wall_distance > 0)) &
            call stop_all(cfg%where('potential', 'wall_distance')//': must be > 0 (a length in '// &
                          trim(cfg%units%length)//'; leave it out for the default: half the mean boundary edge)')
    end subroutine validate_walls

    !> The rest of the checks for an EAM scene (no LJ keys).
    subroutine validate_eam(cfg)
        type(config_t), intent(inout) :: cfg
        if (len_trim(cfg%potential_file) == 0) call stop_all(cfg%path//': &potential: file: missing (the LAMMPS '// &
            "potential file, e.g. file = '/usr/share/lammps/potentials/Cu_u3.eam')")
        if (cfg%pot_style%needs_elements .and. len_trim(cfg%elements(1)) == 0) call stop_all(cfg%path// &
            ": &potential: elements: missing (element names of atom types 1, 2, ..., e.g. elements = 'Cu', 'Ni')")
        if (cfg%nml%gives_any('potential', 'epsilon sigma cutoff')) call stop_all(cfg%where('potential', 'style')// &
            ': epsilon, sigma and cutoff are for the LJ styles (an EAM file sets its own cutoff)')
        if (cfg%pot_style%needs_metal_units .and. cfg%units%name /= 'metal') &
            call stop_all(cfg%where('run', 'units')//" = '"//trim(cfg%units%name)// &
            "': the EAM styles need units = 'metal' (LAMMPS EAM files are in eV and Angstrom)")
        call validate_run_settings(cfg)
        if (cfg%list == 'all_pairs' .and. .not. cfg%pot_style%all_pairs) call stop_all(cfg%where('neighbor', 'list')// &
            ": 'all_pairs' is not available with EAM (use 'auto' or 'cells')")
    end subroutine validate_eam

    !> LJ keys, then the settings common to every potential.
    subroutine validate_lj(cfg)
        type(config_t), intent(inout) :: cfg
        integer :: i, j
        if (is_unset(cfg%epsilon(1, 1))) call stop_all(cfg%path//': &potential: epsilon: missing (energy in '// &
                                                       trim(cfg%units%energy)//')')
        if (is_unset(cfg%sigma(1, 1))) call stop_all(cfg%path//': &potential: sigma: missing (length in '// &
                                                     trim(cfg%units%length)//')')
        do j = 1, max_types
            do i = 1, max_types
                if (.not. is_unset(cfg%epsilon(i, j)) .and. cfg%epsilon(i, j) < 0) &
                    call stop_all(cfg%where('potential', 'epsilon')//': must be >= 0')
                if (.not. is_unset(cfg%sigma(i, j)) .and. cfg%sigma(i, j) <= 0) &
                    call stop_all(cfg%where('potential', 'sigma')//': must be > 0')
                if (.not. is_unset(cfg%pair_cutoff(i, j)) .and. cfg%pair_cutoff(i, j) <= 0) &
                    call stop_all(cfg%where('potential', 'pair_cutoff')//': must be > 0')
            end do
        end do
        if (cfg%nml%find('potential', 'cutoff') == 0) &
            call stop_all(cfg%path//': &potential: cutoff: missing (a length in '//trim(cfg%units%length)// &
                          ', or 0 for no cutoff in a non-periodic scene)')
        if (cfg%cutoff < 0) call stop_all(cfg%where('potential', 'cutoff')//': must be > 0 (or 0 for no cutoff)')
        if (cfg%cutoff == 0 .and. any(cfg%periodic(1:cfg%dimension))) &
            call stop_all(cfg%where('potential', 'cutoff')//' = 0 (no cutoff): only for scenes with no periodic '// &
                          'dimension (set periodic = .false., .false., .false. or give a cutoff)')
        if (cfg%cutoff == 0 .and. .not. cfg%pot_style%no_cutoff) &
            call stop_all(cfg%where('potential', 'cutoff')//' = 0 (no cutoff): only with style = '// &
                          quoted_list(pots%name, ' or ', pots%no_cutoff))
        call validate_run_settings(cfg)
    end subroutine validate_lj

    !> &integrator: the style's own keys, and the time step (given or the units' default).
    subroutine validate_integrator(cfg)
        type(config_t), intent(inout) :: cfg
        character(len=:), allocatable :: es_styles
        es_styles = quoted_list(integs%name, ' or ', has_word(integs%keys, 'terrace_height'))
        if (cfg%integ_style%time_stepped) then
            if (cfg%nml%gives_any('integrator', 'terrace_height target_mean_dt')) &
                call stop_all(cfg%where('integrator', 'style')//': terrace_height and target_mean_dt are for '// &
                              'style = '//es_styles)
        else if (cfg%integ_style%exact_time) then
            if (cfg%nml%find('integrator', 'dt') > 0) call stop_all(cfg%where('integrator', 'dt')// &
                ': energy stepping chooses its own time steps (give terrace_height or target_mean_dt instead)')
            if (cfg%nml%find('integrator', 'terrace_height') > 0 .and. cfg%nml%find('integrator', 'target_mean_dt') > 0) &
                call stop_all(cfg%where('integrator', 'target_mean_dt')//': give either terrace_height or target_mean_dt')
            if (cfg%nml%find('integrator', 'terrace_height') > 0 .and. .not. (cfg%terrace_height > 0)) &
                call stop_all(cfg%where('integrator', 'terrace_height')//': must be > 0 (an energy in '// &
                              trim(cfg%units%energy)//')')
            if (cfg%nml%find('integrator', 'target_mean_dt') > 0 .and. .not. (cfg%target_mean_dt > 0)) &
                call stop_all(cfg%where('integrator', 'target_mean_dt')//': must be > 0 (a time in '// &
                              trim(cfg%units%time)//')')
            if (.not. (cfg%terrace_height > 0) .and. .not. (cfg%target_mean_dt > 0)) &
                call stop_all(cfg%path//': &integrator: terrace_height: missing (energy stepping needs terrace_height '// &
                              'in '//trim(cfg%units%energy)//', or target_mean_dt in '//trim(cfg%units%time)//')')
            if (.not. (cfg%root_tolerance > 0 .and. cfg%root_tolerance <= 1.0e-2_dp)) &
                call stop_all(cfg%where('integrator', 'root_tolerance')//': must be in (0, 1e-2] (relative to the '// &
                              'terrace height)')
            if (cfg%pot_style%jumps_at_cutoff .and. .not. cfg%shift .and. cfg%cutoff > 0) &
                call stop_all(cfg%where('potential', 'shift')//": energy stepping needs a continuous potential: the "// &
                              "truncated, unshifted '"//trim(cfg%potential)//"' jumps at the cutoff (set shift = "// &
                              '.true., use style = '//quoted_list(pots%name, ' or ', pots%pair .and. &
                              .not. (pots%jumps_at_cutoff .or. pots%stepped))//', or cutoff = 0 in a free scene)')
        else if (cfg%integ_style%event_driven) then
            call validate_event_driven(cfg)
        else
            call stop_all(cfg%where('integrator', 'style')//" = '"//trim(cfg%integrator)// &
                          "': unknown integrator (allowed: "//quoted_list(integs%name, ', ')//')')
        end if
        if (cfg%nml%find('integrator', 'dt') > 0 .and. cfg%dt <= 0) &
            call stop_all(cfg%where('integrator', 'dt')//': must be > 0 (a time in '//trim(cfg%units%time)//')')
        if (cfg%dt <= 0) cfg%dt = cfg%units%default_dt
    end subroutine validate_integrator

    !> &neighbor skin, buffer_tolerance, every and check: the list's skin and rebuild schedule.
    subroutine validate_list_schedule(cfg)
        type(config_t), intent(inout) :: cfg
        character(len=16) :: key
        if (cfg%nml%find('neighbor', 'skin') > 0 .and. cfg%skin < 0) &
            call stop_all(cfg%where('neighbor', 'skin')//': must be >= 0 (a length in '//trim(cfg%units%length)//')')
        if (cfg%nml%find('neighbor', 'skin') > 0 .and. cfg%skin == 0 .and. cfg%integ_style%exact_time .and. &
            .not. (cfg%cutoff == 0 .and. len_trim(cfg%mesh_file) == 0)) &
            call stop_all(cfg%where('neighbor', 'skin')//' = 0: energy stepping needs a skin > 0 (its events are '// &
                          'timed by the list''s expiry, which a zero skin puts at every instant; a length in '// &
                          trim(cfg%units%length)//')')
        if (cfg%nml%find('neighbor', 'buffer_tolerance') > 0) call check_buffer_tolerance(cfg)
        if (cfg%skin < 0) cfg%skin = cfg%units%default_skin
        if (cfg%list_every < 1) call stop_all(cfg%where('neighbor', 'every')// &
                                              ': must be >= 1 (steps between list checks, or rebuilds with check = .false.)')
        if (cfg%list_every > 1 .or. .not. cfg%list_check) then
            key = merge('every', 'check', cfg%list_every > 1)
            if (cfg%buffer_tolerance > 0) key = 'buffer_tolerance'     ! (the key that set this schedule)
            if (cfg%integ_style%exact_time) call stop_all(cfg%where('neighbor', trim(key))// &
                ': energy stepping needs the exact list (its events are timed by the list''s expiry; allowed with '// &
                'energy stepping: every = 1, check = .true.)')
            if (len_trim(cfg%mesh_file) > 0) call stop_all(cfg%where('neighbor', trim(key))// &
                ': a mesh scene needs the exact list (contact and the element halo; allowed: every = 1, check = .true.)')
            if (cfg%integ_style%event_driven) call stop_all(cfg%where('neighbor', trim(key))// &
                ': event-driven integration predicts its events over its own cell grid and builds the list '// &
                'once, for the start''s overlap check (allowed with it: every = 1, check = .true.)')
        end if
    end subroutine validate_list_schedule

    !> &neighbor outer_skin: 0 (off), or a skin > skin for the built list that velocity Verlet prunes
    !> the force pass's list from (terrace_engine's engine_list_due): with the exact list when an atom
    !> has moved skin/2, with prune_every on its fixed schedule; a fixed 3-D box only
    !> (what the potential allows the scene planner checks).
    subroutine check_outer_skin(cfg)
        type(config_t), intent(in) :: cfg
        character(len=:), allocatable :: at
        character(len=32) :: s
        at = cfg%where('neighbor', 'outer_skin')
        write (s, '(g0.6)') cfg%skin
        if (cfg%outer_skin < 0 .or. (cfg%outer_skin > 0 .and. cfg%outer_skin <= cfg%skin)) &
            call stop_all(at//': must be 0 (off) or > skin = '//trim(s)//' (a length in '//trim(cfg%units%length)//')')
        if (cfg%outer_skin == 0) return
        if (cfg%buffer_tolerance > 0) call stop_all(at//': give outer_skin or buffer_tolerance, not both '// &
            '(with prune_every, buffer_tolerance sets both skins; allowed with buffer_tolerance: 0)')
        if (.not. (cfg%list_every == 1 .and. cfg%list_check) .and. cfg%prune_every == 0) call stop_all(at// &
            ': only with the exact list (every = 1, check = .true.), or with prune_every and a fixed schedule '// &
            '(allowed otherwise: 0)')
        call check_outer_list_run(cfg, at)
    end subroutine check_outer_skin

    !> &neighbor prune_every: 0 (off), or the steps between the prunes of the force pass's list from
    !> the outer list on a fixed schedule (every = a multiple of it, check = .false.): skins from
    !> buffer_tolerance (for every and for prune_every steps) or given (skin, outer_skin).
    subroutine check_prune_every(cfg)
        type(config_t), intent(in) :: cfg
        character(len=:), allocatable :: at
        character(len=32) :: s
        at = cfg%where('neighbor', 'prune_every')
        if (cfg%prune_every < 0) call stop_all(at//': must be >= 0 (0: off; steps between the prunes of the '// &
                                               'force pass''s list)')
        if (cfg%prune_every == 0) return
        write (s, '(i0)') cfg%list_every
        if (cfg%list_check .or. cfg%list_every == 1) call stop_all(at//': only with a fixed schedule (every > 1 and '// &
            'check = .false., or buffer_tolerance; allowed with the exact list: 0, where outer_skin prunes when an '// &
            'atom has moved skin/2)')
        if (mod(cfg%list_every, cfg%prune_every) /= 0 .or. cfg%prune_every >= cfg%list_every) call stop_all(at// &
            ': must divide every = '//trim(s)//' and be smaller (the steps between prunes; builds come every `every` steps)')
        if (cfg%buffer_tolerance <= 0 .and. cfg%outer_skin == 0) call stop_all(at//': needs outer_skin (the built '// &
            'list''s skin, > skin) or buffer_tolerance (which sets both skins)')
        call check_outer_list_run(cfg, at)
    end subroutine check_prune_every

    !> What an outer list needs of the run (outer_skin, prune_every; at names the key, whose allowed
    !> value otherwise is 0).
    subroutine check_outer_list_run(cfg, at)
        type(config_t), intent(in) :: cfg
        character(len=*), intent(in) :: at
        character(len=*), parameter :: allowed = '0'
        if (.not. cfg%integ_style%time_stepped) call stop_all(at//': only with &integrator style = '// &
            quoted_list(integs%name, ' or ', integs%time_stepped)//' (allowed with style = '''// &
            trim(cfg%integrator)//''': '//allowed//')')
        if (cfg%barostat /= 'none') call stop_all(at//': only with a fixed box (allowed with a barostat: '//allowed//')')
        if (len_trim(cfg%minimize) > 0) call stop_all(at//': not with &minimize (allowed: '//allowed//')')
        if (cfg%dimension /= 3) call stop_all(at//': only for 3-D runs (allowed with &run dimension = '// &
            int_text(cfg%dimension)//': '//allowed//')')
        if (len_trim(cfg%mesh_file) > 0) call stop_all(at//': not for a mesh scene (allowed: '//allowed//')')
        if (cfg%list == 'all_pairs' .or. cfg%list == 'clusters') call stop_all(at//": only with &neighbor list = "// &
            "'auto' or 'cells' (allowed with list = '"//trim(cfg%list)//"': "//allowed//')')
    end subroutine check_outer_list_run

    !> &neighbor list: the kind of pair search.
    subroutine validate_list_kind(cfg)
        type(config_t), intent(in) :: cfg
        select case (cfg%list)
        case ('auto', 'cells', 'all_pairs')
        case ('clusters')
            if (cfg%precision /= 'mixed' .or. cfg%dimension /= 3) call stop_all(cfg%where('neighbor', 'list')// &
                " = 'clusters': the cluster-pair list serves the mixed-precision kernel of 3-D runs only "// &
                "(&potential precision = 'mixed', &run dimension = 3; otherwise allowed: 'auto', 'cells', 'all_pairs')")
        case default
            call stop_all(cfg%where('neighbor', 'list')//" = '"//trim(cfg%list)// &
                          "': unknown (allowed: 'auto', 'cells', 'all_pairs', 'clusters')")
        end select
        if (cfg%list == 'all_pairs' .and. any(cfg%periodic(1:cfg%dimension))) &
            call stop_all(cfg%where('neighbor', 'list')//" = 'all_pairs': only for scenes with no periodic dimension")
        if (cfg%cutoff == 0 .and. (cfg%list == 'cells' .or. cfg%list == 'clusters')) &
            call stop_all(cfg%where('neighbor', 'list')//" = '"//trim(cfg%list)//"': needs a cutoff (&potential cutoff > 0)")
        if (cfg%images /= 'auto' .and. cfg%images /= 'copies') call stop_all(cfg%where('neighbor', 'images')//" = '"// &
            trim(cfg%images)//"': unknown (allowed: 'auto', 'copies')")
    end subroutine validate_list_kind

    !> Integrator, neighbour and output settings (any potential).
    subroutine validate_run_settings(cfg)
        type(config_t), intent(inout) :: cfg
        call validate_integrator(cfg)
        call validate_list_schedule(cfg)
        if (cfg%integ_style%time_stepped) then
            call check_steps('run', 'run_time', cfg%run_time)
            call check_steps('output', 'thermo_interval', cfg%thermo_interval)
            call check_steps('output', 'trajectory_interval', cfg%trajectory_interval)
            call check_steps('output', 'checkpoint_interval', cfg%checkpoint_interval)
        else
            ! energy stepping and event-driven runs: every interval is a calendar entry; one that
            ! puts more than max_events entries into run_time would never let the run finish
            call check_events('output', 'thermo_interval', cfg%thermo_interval, 'thermo samples')
            call check_events('output', 'trajectory_interval', cfg%trajectory_interval, 'frames')
            call check_events('output', 'checkpoint_interval', cfg%checkpoint_interval, 'checkpoints')
            call check_events('integrator', 'target_mean_dt', cfg%target_mean_dt, 'events')
            call check_events('barostat', 'interval', cfg%barostat_interval, 'volume moves')
        end if
        call validate_list_kind(cfg)

        if (cfg%nml%find('output', 'thermo_every') > 0 .and. cfg%thermo_every <= 0) &
            call stop_all(cfg%where('output', 'thermo_every')//': must be > 0 (steps)')
        if (cfg%nml%find('output', 'thermo_interval') > 0 .and. cfg%thermo_interval <= 0) &
            call stop_all(cfg%where('output', 'thermo_interval')//': must be > 0 (a time in '//trim(cfg%units%time)//')')
        if (cfg%thermo_every > 0 .and. cfg%thermo_interval > 0) &
            call stop_all(cfg%where('output', 'thermo_interval')//': give either thermo_every or thermo_interval')
        call validate_thermostat(cfg)
        call validate_barostat(cfg)
        call validate_minimize(cfg)
        if (cfg%nml%find('neighbor', 'outer_skin') > 0) call check_outer_skin(cfg)
        if (cfg%nml%find('neighbor', 'prune_every') > 0) call check_prune_every(cfg)
        call validate_outputs(cfg)
    contains

        !> A time converted into steps must give a step count the run can count (at most 1e15).
        subroutine check_steps(group, key, time)
            character(len=*), intent(in) :: group, key
            real(dp), intent(in) :: time
            character(len=32) :: s
            if (.not. (time > 0)) return
            if (time < 0.5_dp*cfg%dt) call stop_all(cfg%where(group, key)//': '//sci_text(time)//' '// &
                trim(cfg%units%time)//' is shorter than half a time step (dt = '//sci_text(cfg%dt)//' '// &
                trim(cfg%units%time)//'), and velocity Verlet counts whole steps (allowed: at least dt/2)')
            if (time/cfg%dt <= 1.0e15_dp) return
            write (s, '(es10.3)') time/cfg%dt
            call stop_all(cfg%where(group, key)//': '//trim(adjustl(s))//' time steps of dt (the most a run '// &
                          'may count is 1e15; give a larger dt or a shorter time)')
        end subroutine check_steps

        !> An interval of a calendar entry: at least run_time / max_events, and above the resolution of
        !> the run's time (a run of run_time cannot tell times closer than run_time * 1e-15 apart).
        subroutine check_events(group, key, interval, what)
            character(len=*), intent(in) :: group, key, what
            real(dp), intent(in) :: interval
            character(len=32) :: s, m
            if (.not. (interval > 0 .and. cfg%run_time > 0)) return
            if (cfg%run_time/interval <= max_events) return
            write (s, '(es10.3)') cfg%run_time/interval
            write (m, '(es10.3)') cfg%run_time/max_events
            call stop_all(cfg%where(group, key)//': '//trim(adjustl(s))//' '//what//' in run_time (the most a run '// &
                          'may schedule is 1e12: the run would not finish; allowed: at least '//trim(adjustl(m))// &
                          ' '//trim(cfg%units%time)//' for this run_time)')
        end subroutine check_events

    end subroutine validate_run_settings

    !> Stepped pair styles (hard_sphere, square_well): per type pair diameter, and for a square
    !> well its depth and outer radius (well_radius, or well_lambda x diameter); only event-driven
    !> integration runs them. Table completeness per type is checked with the scene.
    subroutine validate_stepped(cfg)
        type(config_t), intent(inout) :: cfg
        integer :: i, j
        logical :: sw
        sw = has_word(cfg%pot_style%keys, 'well_depth')
        if (.not. cfg%integ_style%stepped_potentials) call stop_all(cfg%where('integrator', 'style')//" = '"// &
            trim(cfg%integrator)//"': cannot run &potential style = '"//trim(cfg%potential)//"' (its forces are "// &
            'impulses at the steps); use &integrator style='// &
            quoted_list(integs%name, ' or ', integs%stepped_potentials))
        if (cfg%nml%gives_any('potential', 'epsilon sigma cutoff pair_cutoff shift')) call stop_all(cfg%where('potential', 'style')//" = '"// &
            trim(cfg%potential)//"': epsilon, sigma, cutoff, pair_cutoff and shift are for the LJ styles (give "// &
            'diameter'//trim(merge(', well_depth and well_lambda or well_radius', '                                           ', &
            sw))//')')
        if (is_unset(cfg%diameter(1, 1))) call stop_all(cfg%path//': &potential: diameter: missing (the hard-core '// &
            'diameter of type pair (1,1) in '//trim(cfg%units%length)//')')
        if (.not. sw) then
            call only_for('well_depth')
            call only_for('well_lambda')
            call only_for('well_radius')
        else
            if (is_unset(cfg%well_depth(1, 1))) call stop_all(cfg%path//': &potential: well_depth: missing (the '// &
                'depth eps > 0 of the well of type pair (1,1) in '//trim(cfg%units%energy)//')')
            if (is_unset(cfg%well_lambda(1, 1)) .and. is_unset(cfg%well_radius(1, 1))) call stop_all(cfg%path// &
                ': &potential: well_lambda: missing (the outer radius of the well in diameters, > 1; or '// &
                'well_radius in '//trim(cfg%units%length)//')')
        end if
        do j = 1, max_types
            do i = 1, max_types
                if (.not. is_unset(cfg%diameter(i, j)) .and. .not. (cfg%diameter(i, j) > 0)) &
                    call stop_all(cfg%where('potential', 'diameter')//': must be > 0 (a length in '// &
                                  trim(cfg%units%length)//')')
                if (.not. is_unset(cfg%well_depth(i, j)) .and. .not. (cfg%well_depth(i, j) > 0)) &
                    call stop_all(cfg%where('potential', 'well_depth')//': must be > 0 (the depth of an attractive '// &
                                  'well in '//trim(cfg%units%energy)//')')
                if (.not. is_unset(cfg%well_lambda(i, j)) .and. .not. (cfg%well_lambda(i, j) > 1)) &
                    call stop_all(cfg%where('potential', 'well_lambda')//': must be > 1 (the outer radius of the '// &
                                  'well in diameters)')
                if (.not. is_unset(cfg%well_lambda(i, j)) .and. .not. is_unset(cfg%well_radius(i, j))) &
                    call stop_all(cfg%where('potential', 'well_radius')//': give either well_lambda or well_radius '// &
                                  'for a type pair, not both')
                if (.not. is_unset(cfg%well_radius(i, j)) .and. .not. is_unset(cfg%diameter(i, j))) then
                    if (.not. (cfg%well_radius(i, j) > cfg%diameter(i, j))) call stop_all(cfg%where('potential', &
                        'well_radius')//': must be larger than the diameter of its type pair')
                end if
            end do
        end do
        call validate_run_settings(cfg)
    contains
        !> A key of another stepped style: refused with the styles that take it.
        subroutine only_for(key)
            character(len=*), intent(in) :: key
            if (cfg%nml%find('potential', key) > 0) call stop_all(cfg%where('potential', key)//': only for style = '// &
                quoted_list(pots%name, ' or ', has_word(pots%keys, key)))
        end subroutine only_for
    end subroutine validate_stepped

    !> Event-driven integration: stepped potentials only, a time-scheduled run in a fully
    !> periodic 3-D box, Andersen's thermostat or none; checkpoints by time (checkpoint_interval).
    subroutine validate_event_driven(cfg)
        type(config_t), intent(inout) :: cfg
        class(thermostat_t), allocatable :: proto
        if (.not. cfg%pot_style%stepped) call stop_all(cfg%where('potential', &
            'style')//" = '"//trim(cfg%potential)//"': event-driven integration runs stepped potentials only "// &
            '('//quoted_list(pots%name, ', ', pots%stepped)//'); use &integrator style='// &
            quoted_list(integs%name, ' or ', integs%smooth_potentials)//' for it')
        if (cfg%nml%find('integrator', 'dt') > 0) call stop_all(cfg%where('integrator', 'dt')// &
            ': event-driven integration has no time step (it moves from event to event)')
        if (cfg%nml%gives_any('integrator', 'terrace_height target_mean_dt root_tolerance')) call stop_all(cfg%where('integrator', 'style')// &
            ': terrace_height, target_mean_dt and root_tolerance are for style = '// &
            quoted_list(integs%name, ' or ', has_word(integs%keys, 'terrace_height')))
        if (cfg%n_steps >= 0) call stop_all(cfg%where('run', 'n_steps')//': event-driven integration has no steps; '// &
            'give run_time (in '//trim(cfg%units%time)//')')
        if (cfg%nml%find('output', 'thermo_every') > 0) call stop_all(cfg%where('output', 'thermo_every')// &
            ': event-driven integration samples at exact times; give thermo_interval (in '//trim(cfg%units%time)//')')
        if (cfg%nml%find('output', 'trajectory_every') > 0) call stop_all(cfg%where('output', 'trajectory_every')// &
            ': event-driven integration writes frames at exact times; give trajectory_interval (in '// &
            trim(cfg%units%time)//')')
        if (cfg%nml%find('thermostat', 'style') > 0) then
            call new_thermostat(cfg%thermostat, thermostat_params_t(), proto)
            if (proto%active() .and. .not. proto%traits%collides_atoms) call stop_all(cfg%where('thermostat', &
                'style')//" = '"//trim(cfg%thermostat)//"': not available with event-driven integration (allowed: "// &
                thermostat_styles_colliding()//"'none')")
            if (cfg%nml%find('thermostat', 'interval') > 0) call stop_all(cfg%where('thermostat', 'interval')// &
                ': event-driven integration runs Andersen collisions atom by atom at exact times (no interval)')
            if (cfg%nml%find('thermostat', 'zero_momentum') > 0 .and. cfg%zero_momentum) call stop_all( &
                cfg%where('thermostat', 'zero_momentum')//': not available with event-driven integration '// &
                '(allowed: .false.; Andersen collisions do not hold the total momentum)')
        end if
        if (cfg%nml%find('output', 'checkpoint_every') > 0) call stop_all(cfg%where('output', 'checkpoint_every')// &
            ': event-driven integration has no steps; give checkpoint_interval (a time in '//trim(cfg%units%time)//')')
        if (cfg%dimension /= 3) call stop_all(cfg%where('run', 'dimension')//': event-driven integration is 3-D')
        if (.not. all(cfg%periodic)) call stop_all(cfg%where('system', 'periodic')// &
            ': event-driven integration needs a periodic box in x, y and z')
    end subroutine validate_event_driven

    !> Output files: intervals, fields, and no silent overwrite of an existing file.
    subroutine validate_outputs(cfg)
        type(config_t), intent(inout) :: cfg
        character(len=64) :: word
        integer :: i, j, ios
        logical :: there
        if (cfg%nml%find('output', 'trajectory_every') > 0 .and. cfg%trajectory_every <= 0) &
            call stop_all(cfg%where('output', 'trajectory_every')//': must be > 0')
        if (cfg%nml%find('output', 'trajectory_interval') > 0 .and. .not. (cfg%trajectory_interval > 0)) &
            call stop_all(cfg%where('output', 'trajectory_interval')//': must be > 0 (a time in '// &
                          trim(cfg%units%time)//')')
        if (cfg%trajectory_every > 0 .and. cfg%trajectory_interval > 0) &
            call stop_all(cfg%where('output', 'trajectory_interval')//': give either trajectory_every or '// &
                          'trajectory_interval')
        ! neither trajectory_every nor trajectory_interval: frames at the thermo samples (src/app/terrace.f90)
        i = 1
        do
            read (cfg%trajectory_fields(i:), *, iostat=ios) word
            if (ios /= 0 .or. len_trim(word) == 0) exit
            select case (trim(word))
            case ('position', 'velocity', 'force', 'image')
            case default
                call stop_all(cfg%where('output', 'trajectory_fields')//": unknown field '"//trim(word)// &
                              "' (allowed: position, velocity, force, image)")
            end select
            j = index(cfg%trajectory_fields(i:), trim(word))
            i = i + j - 1 + len_trim(word)
            if (i > len_trim(cfg%trajectory_fields)) exit
        end do
        if (index(cfg%trajectory_fields, 'image') > 0 .and. index(cfg%trajectory_fields, 'position') == 0) &
            call stop_all(cfg%where('output', 'trajectory_fields')//": 'image' needs 'position' too")
        ! a trajectory is expensive to make: an existing one is never replaced silently (the small
        ! text outputs are, as in other MD codes)
        call validate_checkpoints(cfg)
        ! (a restart appends to the trajectory of the interrupted run)
        if (.not. cfg%overwrite .and. len_trim(cfg%trajectory_file) > 0 .and. len_trim(cfg%read_checkpoint) == 0) then
            inquire (file=trim(cfg%trajectory_file), exist=there)
            if (there) call stop_all(cfg%where('output', 'trajectory_file')//" = '"//trim(cfg%trajectory_file)// &
                "': the file exists (set overwrite = .true. to replace it, or choose another name)")
        end if
    end subroutine validate_outputs

    !> Checkpoint and batch-job keys (doc/checkpoints.md). Checks that need files (a missing or
    !> foreign checkpoint, an unwritable path) are made when the run starts.
    subroutine validate_checkpoints(cfg)
        type(config_t), intent(inout) :: cfg
        logical :: has_file
        has_file = len_trim(cfg%checkpoint_file) > 0
        if (cfg%nml%find('output', 'checkpoint_interval') > 0 .and. .not. (cfg%checkpoint_interval > 0)) &
            call stop_all(cfg%where('output', 'checkpoint_interval')//': must be > 0 (a time in '// &
                          trim(cfg%units%time)//')')
        if (cfg%nml%find('output', 'checkpoint_every') > 0 .and. cfg%checkpoint_every <= 0) &
            call stop_all(cfg%where('output', 'checkpoint_every')//': must be > 0 (steps)')
        if (cfg%checkpoint_every > 0 .and. cfg%checkpoint_interval > 0) &
            call stop_all(cfg%where('output', 'checkpoint_interval')//': give either checkpoint_every or '// &
                          'checkpoint_interval')
        if (cfg%checkpoint_every > 0 .and. cfg%integ_style%exact_time) &
            call stop_all(cfg%where('output', 'checkpoint_every')//': energy stepping has no fixed steps; give '// &
                          'checkpoint_interval (a time in '//trim(cfg%units%time)//')')
        if ((cfg%checkpoint_every > 0 .or. cfg%checkpoint_interval > 0) .and. .not. has_file) &
            call stop_all(cfg%path//': &output: checkpoint_file: missing (checkpoint_interval and checkpoint_every '// &
                          'need a file name)')
        if (cfg%nml%find('output', 'checkpoint_file') > 0 .and. .not. has_file) &
            call stop_all(cfg%where('output', 'checkpoint_file')//': must not be empty')
        if (cfg%nml%find('run', 'walltime_limit') > 0 .and. .not. (cfg%walltime_limit > 0)) &
            call stop_all(cfg%where('run', 'walltime_limit')//': must be > 0 (seconds of wall-clock time)')
        if (cfg%walltime_limit > 0 .and. .not. has_file) &
            call stop_all(cfg%where('run', 'walltime_limit')//': needs &output checkpoint_file (the run stops '// &
                          'with a checkpoint)')
        if (cfg%nml%find('system', 'read_checkpoint') > 0 .and. len_trim(cfg%read_checkpoint) == 0) &
            call stop_all(cfg%where('system', 'read_checkpoint')//': must not be empty')
        if (cfg%nml%find('system', 'restart_outputs') > 0) then
            if (cfg%restart_outputs /= 'append' .and. cfg%restart_outputs /= 'new') &
                call stop_all(cfg%where('system', 'restart_outputs')//" = '"//trim(cfg%restart_outputs)// &
                              "': unknown (allowed: 'append', 'new')")
            if (len_trim(cfg%read_checkpoint) == 0) &
                call stop_all(cfg%where('system', 'restart_outputs')//': needs &system read_checkpoint (it says '// &
                              'where a restart writes its outputs)')
        end if
    end subroutine validate_checkpoints

end module terrace_config
