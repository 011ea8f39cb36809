!> Memory guard: before the scene is built, estimate the memory it needs and refuse a scene that
!> cannot fit in the memory this node has available, with the estimate in the message.
!>
!>   bytes ~ nprocs * process_base + N * (per_atom + 4 * n_neigh),
!>   n_neigh = (4/3) pi (r_cut + skin)^3 rho          (3-D; pi (r_cut + skin)^2 rho in 2-D)
!>
!> per_atom covers positions, velocities, forces, ids, types, images, the previous positions of
!> the list check, ghosts and the gather buffers; 4 n_neigh the neighbour list (int32 entries,
!> half list with room to grow). N comes from the lattice (cells x basis) or from the header of a
!> data file (already bounded there by the file's size). The available memory is MemAvailable of
!> /proc/meminfo, or the cgroup limit (memory.max) when that is lower.
module terrace_memory_guard
    use terrace_kinds, only: dp, i8, pi
    use terrace_text, only: fixed
    use terrace_config, only: config_t
    use terrace_mpi_env, only: world
    use terrace_errors, only: check_all
    use terrace_lattice, only: lattice_basis, lattice_cell
    implicit none
    private

    public :: check_memory, estimate_scene_bytes, available_memory_bytes

    real(dp), parameter :: process_base = 64.0_dp*2**20    !< libraries, MPI and HDF5 buffers per rank
    real(dp), parameter :: per_atom = 400.0_dp             !< per-atom arrays (bytes), ghosts included

contains

    !> Collective: stops every rank when the estimate exceeds the available memory.
    subroutine check_memory(cfg)
        type(config_t), intent(in) :: cfg
        real(dp) :: need, have, natoms
        character(len=:), allocatable :: msg
        character(len=32) :: a, b, c
        msg = ''
        if (world%rank == 0) then
            need = estimate_scene_bytes(cfg, world%nprocs, natoms)
            have = available_memory_bytes()
            if (need > have .and. have > 0) then
                write (a, '(es10.3)') natoms
                b = fixed(need/2.0_dp**30, 1)
                c = fixed(have/2.0_dp**30, 1)
                msg = source(cfg)//': the scene needs about '//trim(lead0(b))//' GiB ('//trim(adjustl(a))// &
                      ' atoms), more than the '//trim(lead0(c))//' GiB of memory available on this node '// &
                      '(MemAvailable or the cgroup limit); make the scene smaller'
            end if
        end if
        call check_all(len(msg) == 0, msg)
    end subroutine check_memory

    function source(cfg) result(s)
        type(config_t), intent(in) :: cfg
        character(len=:), allocatable :: s
        if (len_trim(cfg%lattice) > 0) then
            s = cfg%where('system', 'cells')
        else
            s = cfg%scene_source()
        end if
    end function source

    !> '.5' -> '0.5'
    function lead0(s) result(t)
        character(len=*), intent(in) :: s
        character(len=:), allocatable :: t
        t = trim(adjustl(s))
        if (len(t) > 0) then
            if (t(1:1) == '.') t = '0'//t
        end if
    end function lead0

    !> Estimated bytes of the whole run on nprocs ranks; natoms is the atom count it assumed.
    real(dp) function estimate_scene_bytes(cfg, nprocs, natoms) result(bytes)
        type(config_t), intent(in) :: cfg
        integer, intent(in) :: nprocs
        real(dp), intent(out) :: natoms
        real(dp), allocatable :: basis(:, :)
        real(dp) :: cell(3), volume, rho, reach, nneigh
        integer :: d
        natoms = 0; rho = 0
        if (len_trim(cfg%lattice) > 0) then
            call lattice_basis(cfg%lattice, basis)
            cell = lattice_cell(cfg%lattice, cfg%lattice_constant, cfg%density, cfg%dimension)
            natoms = size(basis, 2)
            volume = 1
            do d = 1, cfg%dimension
                natoms = natoms*max(cfg%cells(d), 0)
                volume = volume*cell(d)
            end do
            rho = size(basis, 2)/volume
        else if (len_trim(cfg%read_data) > 0) then
            call data_header(trim(cfg%read_data), cfg%dimension, natoms, rho)
        end if
        reach = max(cfg%skin, cfg%outer_skin)      ! (outer_skin: the built list's skin)
        if (cfg%pot_style%needs_file) then       ! the cutoff is in the file: a typical metal's
            reach = reach + 6.0_dp
        else if (cfg%cutoff > 0) then
            reach = reach + max(cfg%cutoff, maxval(cfg%pair_cutoff))
        end if
        if (cfg%dimension == 3) then
            nneigh = 4.0_dp/3.0_dp*pi*reach**3*rho
        else
            nneigh = pi*reach**2*rho
        end if
        nneigh = min(nneigh, max(natoms, 1.0_dp))
        bytes = nprocs*process_base + natoms*(per_atom + 4.0_dp*nneigh)
    end function estimate_scene_bytes

    !> Atom count and number density from a data file's header (0 when not found).
    subroutine data_header(path, dimension, natoms, rho)
        character(len=*), intent(in) :: path
        integer, intent(in) :: dimension
        real(dp), intent(out) :: natoms, rho
        integer :: unit, ios, k, lines
        integer(i8) :: nbytes
        character(len=256) :: buf
        real(dp) :: lo, hi, len3(3)
        natoms = 0; rho = 0; len3 = 1
        open (newunit=unit, file=path, action='read', status='old', iostat=ios)
        if (ios /= 0) return
        lines = 0
        do while (lines < 200)
            read (unit, '(a)', iostat=ios) buf
            if (ios /= 0) exit
            lines = lines + 1
            if (index(buf, 'atoms') > 0 .and. index(buf, 'atom types') == 0) then
                read (buf, *, iostat=ios) natoms
                if (ios /= 0) natoms = 0
            else if (index(buf, 'lo ') > 0 .and. index(buf, 'hi') > 0) then
                read (buf, *, iostat=ios) lo, hi
                k = merge(1, merge(2, 3, index(buf, 'ylo') > 0), index(buf, 'xlo') > 0)
                if (ios == 0 .and. hi > lo) len3(k) = hi - lo
            else if (index(buf, 'Atoms') > 0) then
                exit
            end if
        end do
        close (unit)
        ! a count the file cannot hold is the reader's error (it names the file size), not memory's
        inquire (file=path, size=nbytes)
        if (natoms > nbytes/10.0_dp) natoms = 0
        if (natoms > 0) rho = natoms/product(len3(1:dimension))
    end subroutine data_header

    !> MemAvailable (bytes) of /proc/meminfo, or the cgroup v2 limit when lower; 0 if unknown.
    real(dp) function available_memory_bytes() result(bytes)
        integer :: unit, ios
        character(len=256) :: line
        real(dp) :: kib, limit
        bytes = 0
        open (newunit=unit, file='/proc/meminfo', action='read', status='old', iostat=ios)
        if (ios == 0) then
            do
                read (unit, '(a)', iostat=ios) line
                if (ios /= 0) exit
                if (line(1:13) == 'MemAvailable:') then
                    read (line(14:), *, iostat=ios) kib
                    if (ios == 0) bytes = kib*1024
                    exit
                end if
            end do
            close (unit)
        end if
        open (newunit=unit, file='/sys/fs/cgroup/memory.max', action='read', status='old', iostat=ios)
        if (ios == 0) then
            read (unit, *, iostat=ios) limit
            if (ios == 0 .and. limit > 0 .and. (bytes == 0 .or. limit < bytes)) bytes = limit
            close (unit)
        end if
    end function available_memory_bytes

end module terrace_memory_guard
