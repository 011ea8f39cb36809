!> Checks on the output files, made before the first output is opened (and by --check), and the
!> temporary-name scheme of the small text outputs.
!>
!>  - every output's directory exists and takes a new file; an existing output path is a regular,
!>    writable file (never a device, FIFO or directory);
!>  - no two outputs resolve to the same file, and no output is one of the inputs (the deck, the
!>    data, atoms, H5MD or potential file; a checkpoint may be continued in place);
!>  - the trajectory and checkpoint writers need atom ids 1..N;
!>  - a running job holds an advisory lock (flock) on a lock file beside each output, so that a
!>    second run on the same outputs stops with a clear error instead of clobbering them;
!>  - thermo, forces and final-atoms files are written under a temporary name beside the target
!>    (temporary_name) and renamed over it only when complete (commit_output): a run that fails
!>    leaves the previous file as it was.
module terrace_output_files
    use terrace_kinds, only: i8
    use terrace_config, only: config_t
    use terrace_mpi_env, only: world
    use terrace_errors, only: check_all
    use terrace_file_ops, only: resolve_path, path_kind, is_writable, lock_file, remove_at_exit, keep_at_exit, &
                                process_id, directory_of, path_missing, path_regular, path_directory, &
                                temporary_name, commit_output, write_in_place, output_target
    use terrace_xdmf, only: xdmf_sidecar_path
    use terrace_topology_data, only: topology_data_path, wants_topology_data
    use mpi_f08, only: MPI_Allreduce, MPI_MAX, MPI_INTEGER8
    implicit none
    private

    public :: check_outputs, check_output_ids, commit_small_outputs

    integer, parameter :: nout = 8, nin = 7   !< output 6: a mesh trajectory's XDMF sidecar; 7: the run summary;
    !< 8: a 3-D trajectory's topology for MDAnalysis

    !> Characters a temporary or lock file adds to an output's path ('.' + '.terrace-partial', ...)
    integer, parameter :: name_room = 26

    type :: name_t
        character(len=:), allocatable :: s
    end type name_t

    !> The deck's outputs (by key, path and absolute path: rank 0 resolves them) and its inputs.
    type :: file_set_t
        character(len=16) :: out_keys(nout), in_keys(nin), in_groups(nin)
        type(name_t) :: out_path(nout), out_abs(nout), in_path(nin), in_abs(nin)
    end type file_set_t

contains

    !> Rename the temporary files of the small text outputs (thermo, forces, final atoms) over
    !> their targets, once the run has succeeded: until then the previous files are untouched.
    !> Collective (rank 0 renames).
    subroutine commit_small_outputs(cfg)
        type(config_t), intent(in) :: cfg
        character(len=:), allocatable :: msg
        character(len=512) :: why
        logical :: ok
        msg = ''
        if (world%rank == 0) then
            call one('thermo_file', cfg%thermo_file)
            call one('forces_file', cfg%forces_file)
            call one('final_atoms_file', cfg%final_atoms_file)
            if (len_trim(cfg%trajectory_file) > 0) call one('trajectory_file', topology_data_path(cfg%trajectory_file))
        end if
        call check_all(len(msg) == 0, msg)
    contains
        subroutine one(key, path)
            character(len=*), intent(in) :: key, path
            if (len(msg) > 0 .or. len_trim(path) == 0) return
            if (path_kind(temporary_name(trim(path))) /= path_regular) return
            call commit_output(trim(path), ok, why)
            if (.not. ok) msg = trim(path)//': &output: '//key//': cannot write: '//trim(why)
        end subroutine one
    end subroutine commit_small_outputs

    !> All the output checks (collective). With lock = .true. the outputs are also locked for the
    !> rest of the run (not in --check mode, which writes nothing).
    subroutine check_outputs(cfg, lock)
        type(config_t), intent(in) :: cfg
        logical, intent(in) :: lock
        type(file_set_t) :: files
        character(len=:), allocatable :: msg
        integer :: i
        logical :: ok
        call list_files(cfg, files)
        msg = ''
        ! a checkpointed run writes its small outputs in place (a killed job is continued)
        call write_in_place(len_trim(cfg%checkpoint_file) > 0 .or. len_trim(cfg%read_checkpoint) > 0)
        if (world%rank == 0) then
            do i = 1, nin
                files%in_abs(i)%s = ''
                if (len(files%in_path(i)%s) > 0) files%in_abs(i)%s = resolve_path(files%in_path(i)%s, ok)
            end do
            do i = 1, nout
                files%out_abs(i)%s = ''
                if (len(files%out_path(i)%s) == 0) cycle
                call check_one(cfg, files, i, msg)
                if (len(msg) > 0) exit
            end do
            if (len(msg) == 0 .and. lock) call lock_outputs(cfg, files, msg)
        end if
        call check_all(len(msg) == 0, msg)
    end subroutine check_outputs

    !> The deck's outputs and inputs, by key.
    subroutine list_files(cfg, files)
        type(config_t), intent(in) :: cfg
        type(file_set_t), intent(out) :: files
        files%out_keys = [character(len=16) :: 'thermo_file', 'forces_file', 'final_atoms_file', 'trajectory_file', &
                          'checkpoint_file', 'trajectory_file', 'summary_file', 'trajectory_file']
        files%out_path(1)%s = trim(cfg%thermo_file); files%out_path(2)%s = trim(cfg%forces_file)
        files%out_path(3)%s = trim(cfg%final_atoms_file); files%out_path(4)%s = trim(cfg%trajectory_file)
        files%out_path(5)%s = trim(cfg%checkpoint_file)
        files%out_path(6)%s = ''
        if (len_trim(cfg%mesh_file) > 0 .and. len_trim(cfg%trajectory_file) > 0) &
            files%out_path(6)%s = xdmf_sidecar_path(trim(cfg%trajectory_file))
        files%out_path(7)%s = trim(cfg%summary_file)
        files%out_path(8)%s = ''
        if (wants_topology_data(cfg%trajectory_file, cfg%dimension, len_trim(cfg%mesh_file) > 0)) &
            files%out_path(8)%s = topology_data_path(trim(cfg%trajectory_file))
        files%in_keys = [character(len=16) :: 'input deck', 'read_data', 'atoms_file', 'read_h5md', 'file', &
                         'read_checkpoint', 'mesh_file']
        files%in_groups = [character(len=16) :: '', 'system', 'system', 'system', 'potential', 'system', 'system']
        files%in_path(1)%s = cfg%path; files%in_path(2)%s = trim(cfg%read_data)
        files%in_path(3)%s = trim(cfg%atoms_file); files%in_path(4)%s = trim(cfg%read_h5md)
        files%in_path(5)%s = trim(cfg%potential_file); files%in_path(6)%s = trim(cfg%read_checkpoint)
        files%in_path(7)%s = trim(cfg%mesh_file)
    end subroutine list_files

    !> Lock every output for the rest of the run (msg: why one cannot be locked).
    subroutine lock_outputs(cfg, files, msg)
        type(config_t), intent(in) :: cfg
        type(file_set_t), intent(in) :: files
        character(len=:), allocatable, intent(inout) :: msg
        character(len=:), allocatable :: lock
        integer :: i
        do i = 1, nout
            if (len(files%out_path(i)%s) == 0) cycle
            lock = lock_name(output_target(files%out_path(i)%s))
            select case (lock_file(lock))
            case (1)
                msg = output_where(cfg, files, i)//": another terrace run is writing this output now (it holds "// &
                      'the lock '//lock//'); wait for it to end or choose other output names'
            case (2)
                msg = output_where(cfg, files, i)//': cannot write: cannot create the lock file '//lock
            end select
            if (len(msg) > 0) exit
        end do
    end subroutine lock_outputs

    !> Output i named as the deck names it, for messages.
    function output_where(cfg, files, i) result(s)
        type(config_t), intent(in) :: cfg
        type(file_set_t), intent(in) :: files
        integer, intent(in) :: i
        character(len=:), allocatable :: s
        s = cfg%where('output', trim(files%out_keys(i)))//" = '"//files%out_path(i)%s//"'"
        if (i == 6) s = cfg%where('output', 'trajectory_file')//" = '"//trim(cfg%trajectory_file)// &
                        "': its XDMF sidecar '"//files%out_path(i)%s//"'"
        if (i == 8) s = cfg%where('output', 'trajectory_file')//" = '"//trim(cfg%trajectory_file)// &
                        "': its topology for MDAnalysis '"//files%out_path(i)%s//"'"
    end function output_where

    !> What cannot be done to output i: written (a file replaced) or created (a trajectory, a
    !> checkpoint, a sidecar).
    function output_verb(i) result(s)
        integer, intent(in) :: i
        character(len=:), allocatable :: s
        s = 'cannot write'
        if (i >= 4 .and. i <= 6) s = 'cannot create'
    end function output_verb

    !> Output i: its path can be written (msg says why not), and it is neither an output before it
    !> nor an input (files%out_abs(i): its absolute path).
    subroutine check_one(cfg, files, i, msg)
        type(config_t), intent(in) :: cfg
        type(file_set_t), intent(inout) :: files
        integer, intent(in) :: i
        character(len=:), allocatable, intent(inout) :: msg
        integer :: unit, ios, kind
        character(len=:), allocatable :: probe, dir, where, verb
        character(len=16) :: pid
        logical :: ok
        where = output_where(cfg, files, i); verb = output_verb(i)
        ! a symbolic link is written through: its target's directory must exist and take files
        files%out_abs(i)%s = resolve_path(output_target(files%out_path(i)%s), ok)
        dir = directory_of(output_target(files%out_path(i)%s))
        if (.not. ok) then
            if (path_kind(dir) == path_directory) then
                ! (the directory is there: the absolute path is what cannot be formed)
                msg = where//': '//verb//': the path is too long once the current directory is put '// &
                      'before it (an absolute path has at most 4096 characters; give a shorter name)'
            else
                msg = where//': '//verb//": the directory '"//dir//"' does not exist"
            end if
            return
        end if
        ! beside each output go its temporary file and its lock ('.NAME.terrace-partial', ...)
        if (len(files%out_abs(i)%s) + name_room > 4096) then
            write (pid, '(i0)') len(files%out_abs(i)%s)
            msg = where//': '//verb//': the path has '//trim(pid)//' characters once made absolute; an '// &
                  'output may have at most 4070 (its temporary and lock files beside it need the rest of 4096)'
            return
        end if
        kind = path_kind(files%out_path(i)%s)
        if (kind /= path_missing .and. kind /= path_regular) then
            msg = where//': '//verb//': the path exists and is not a regular file (a directory, '// &
                  'device, pipe or socket is never replaced)'
            return
        end if
        if (kind == path_regular .and. .not. is_writable(files%out_path(i)%s)) then
            msg = where//': '//verb//': the existing file is read-only'
            return
        end if
        ! the directory must take a new file (the temporary output, the lock file)
        write (pid, '(i0)') process_id()
        probe = dir//'/.terrace-probe.'//trim(pid)
        open (newunit=unit, file=probe, status='replace', action='write', iostat=ios)
        if (ios /= 0) then
            msg = where//': '//verb//": cannot create a file in the directory '"//dir//"'"
            return
        end if
        close (unit, status='delete')
        call check_not_another(files, i, where, msg)
    end subroutine check_one

    !> Output i (named `where` in messages) is not the same file as an output before it nor as an
    !> input (a checkpoint may be continued in place).
    subroutine check_not_another(files, i, where, msg)
        type(file_set_t), intent(in) :: files
        integer, intent(in) :: i
        character(len=*), intent(in) :: where
        character(len=:), allocatable, intent(inout) :: msg
        integer :: j
        do j = 1, i - 1
            if (len(files%out_abs(j)%s) == 0) cycle
            if (files%out_abs(j)%s == files%out_abs(i)%s) then
                msg = where//': the same file as &output '//trim(files%out_keys(j))//' ('//files%out_abs(i)%s// &
                      '); give every output its own name'
                return
            end if
        end do
        do j = 1, nin
            if (len(files%in_abs(j)%s) == 0) cycle
            if (i == 5 .and. j == 6) cycle           ! a checkpoint is continued in place
            if (files%in_abs(j)%s == files%out_abs(i)%s) then
                if (j == 1) then
                    msg = where//': the same file as the input deck ('//files%out_abs(i)%s// &
                          '); the run would overwrite its own input'
                else
                    msg = where//': the same file as the input &'//trim(files%in_groups(j))//' '// &
                          trim(files%in_keys(j))//' ('//files%out_abs(i)%s//'); the run would overwrite its input'
                end if
                return
            end if
        end do
    end subroutine check_not_another

    !> The lock file of an output: '.NAME.terrace-lock' in its directory (called with the output's
    !> target, so that two names of one file share one lock).
    function lock_name(path) result(s)
        character(len=*), intent(in) :: path
        character(len=:), allocatable :: s
        integer :: p
        p = index(trim(path), '/', back=.true.)
        s = path(1:p)//'.'//trim(path(p + 1:))//'.terrace-lock'
    end function lock_name

    !> The trajectory and checkpoint writers place every atom by its id in 1..N: with either
    !> output, the ids must be exactly 1..natoms (they are unique already). Collective.
    subroutine check_output_ids(cfg, ids, natoms)
        type(config_t), intent(in) :: cfg
        integer(i8), intent(in) :: ids(:)
        integer(i8), intent(in) :: natoms
        character(len=:), allocatable :: source
        integer(i8) :: mine(2), all(2)
        character(len=24) :: a, b, c
        character(len=:), allocatable :: key
        if (len_trim(cfg%trajectory_file) == 0 .and. len_trim(cfg%checkpoint_file) == 0) return
        mine = [0_i8, 0_i8]
        if (size(ids) > 0) mine = [maxval(ids), -minval(ids)]
        call MPI_Allreduce(mine, all, 2, MPI_INTEGER8, MPI_MAX, world%comm)
        source = cfg%path//': &system'
        if (len_trim(cfg%read_data) > 0) source = trim(cfg%read_data)//': &system: read_data'
        if (len_trim(cfg%atoms_file) > 0) source = trim(cfg%atoms_file)//': &system: atoms_file'
        if (len_trim(cfg%read_h5md) > 0) source = trim(cfg%read_h5md)//': &system: read_h5md'
        key = 'trajectory_file'
        if (len_trim(cfg%trajectory_file) == 0) key = 'checkpoint_file'
        write (a, '(i0)') -all(2)
        write (b, '(i0)') all(1)
        write (c, '(i0)') natoms
        call check_all(all(1) <= natoms .and. -all(2) >= 1, source//': atom ids run from '//trim(a)//' to '// &
                       trim(b)//'; &output '//key//' needs ids 1..'//trim(c)//' (renumber the atoms)')
    end subroutine check_output_ids

end module terrace_output_files
