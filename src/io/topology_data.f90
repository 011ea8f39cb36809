!> The topology beside a 3-D trajectory, for MDAnalysis: a LAMMPS data file in the 'molecular'
!> atom style (id, molecule 1, type, x, y, z: the columns MDAnalysis's DATA parser reads without
!> an atom_style argument) with the box, the masses of the types and the state at the trajectory's
!> first frame, so that
!>     mda.Universe('traj.topology.data', 'traj.h5', format='H5MD', convert_units=False)
!> has the atoms' types and masses and the trajectory's frames. Its name is the trajectory's with
!> '.h5', '.h5md' or '.hdf5' replaced by '.topology.data' ('.topology.data' appended otherwise).
!> Gathered on rank 0 (the state of every atom) and written under a temporary name like the other
!> small text outputs (renamed when the run succeeds: terrace_output_files). Not written for 2-D
!> runs (MDAnalysis reads 3-D boxes only) nor for mesh scenes (per-node masses).
module terrace_topology_data
    use terrace_kinds, only: dp, i8
    use terrace_atoms, only: atoms_t
    use terrace_box, only: box_t
    use terrace_mpi_env, only: world
    use terrace_gather_by_id, only: gather_atoms_by_id
    use terrace_checked_text, only: checked_text_t
    use terrace_file_ops, only: trajectory_sibling
    implicit none
    private

    public :: topology_data_path, write_topology_data, wants_topology_data

contains

    !> The companion's name: traj.h5 -> traj.topology.data ('' for an empty trajectory name).
    function topology_data_path(trajectory) result(path)
        character(len=*), intent(in) :: trajectory
        character(len=:), allocatable :: path
        path = ''
        if (len_trim(trajectory) > 0) path = trajectory_sibling(trajectory, '.topology.data')
    end function topology_data_path

    !> Is a companion written for a trajectory of this run (3-D, not a mesh)?
    logical function wants_topology_data(trajectory, dimension, mesh)
        character(len=*), intent(in) :: trajectory
        integer, intent(in) :: dimension
        logical, intent(in) :: mesh
        wants_topology_data = len_trim(trajectory) > 0 .and. dimension == 3 .and. .not. mesh
    end function wants_topology_data

    !> Write the companion of trajectory (collective; rank 0 writes). ok and msg are rank 0's.
    subroutine write_topology_data(trajectory, atoms, box, units_name, version, ok, msg)
        character(len=*), intent(in) :: trajectory, units_name, version
        type(atoms_t), intent(in) :: atoms
        type(box_t), intent(in) :: box
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        real(dp), allocatable :: all(:, :)
        integer(i8), allocatable :: ids(:)
        type(checked_text_t) :: out
        character(len=160) :: line
        character(len=:), allocatable :: path, name
        integer :: i, d, p
        character(len=*), parameter :: axes(3) = ['x', 'y', 'z']
        ok = .true.; msg = ''
        call gather_atoms_by_id(atoms, .false., ids, all)
        if (world%rank /= 0) return
        path = topology_data_path(trajectory)
        p = index(trim(trajectory), '/', back=.true.)
        name = trim(trajectory(p + 1:))
        call out%open(path, ok, msg)
        if (.not. ok) return
        call out%put('LAMMPS data file: topology of '//name//' for MDAnalysis (Terrace '//version//', units '// &
                     trim(units_name)//'; positions of its first frame)', msg)
        call out%put('', msg)
        write (line, '(i0,a)') size(ids), ' atoms'
        call out%put(line, msg)
        write (line, '(i0,a)') size(atoms%mass), ' atom types'
        call out%put(line, msg)
        call out%put('', msg)
        do d = 1, 3
            write (line, '(es24.16e3,1x,es24.16e3,1x,a)') box%lo(d), box%hi(d), axes(d)//'lo '//axes(d)//'hi'
            call out%put(line, msg)
        end do
        call out%put('', msg)
        call out%put('Masses', msg)
        call out%put('', msg)
        do i = 1, size(atoms%mass)
            write (line, '(i0,1x,es24.16e3)') i, atoms%mass(i)
            call out%put(line, msg)
        end do
        call out%put('', msg)
        call out%put('Atoms # molecular', msg)
        call out%put('', msg)
        do i = 1, size(ids)
            write (line, '(i0,a,i0,3(1x,es24.16e3))') ids(i), ' 1 ', nint(all(1, i)), all(2:4, i)
            call out%put(line, msg)
        end do
        call out%close(ok, msg)
    end subroutine write_topology_data

end module terrace_topology_data
