!> Test driver for check_h5md.py killed: writes 2 frames of 10 atoms (split over the ranks) to the
!> H5MD file named on the command line, then aborts without closing it. The file must stay readable.
program h5md_killed
    use mpi_f08, only: MPI_Init, MPI_Abort, MPI_Barrier, MPI_Comm_rank, MPI_Comm_size, MPI_COMM_WORLD
    use terrace_kinds, only: dp, i8
    use terrace_h5md, only: h5md_writer_t, h5md_layout_t
    implicit none
    integer, parameter :: n = 10
    type(h5md_writer_t) :: w
    integer :: rank, nprocs, nl, id, d, k, types(n)
    integer(i8) :: ids(n)
    real(dp) :: x(3, n)
    logical :: ok
    character(len=256) :: msg, path

    call MPI_Init()
    call MPI_Comm_rank(MPI_COMM_WORLD, rank)
    call MPI_Comm_size(MPI_COMM_WORLD, nprocs)
    call get_command_argument(1, path)
    call w%create(trim(path), MPI_COMM_WORLD, h5md_layout_t(natoms=int(n, i8), dimension=3, &
        box_lo=[0.0_dp, -1.0_dp, 2.0_dp], box_hi=[110.0_dp, 40.0_dp, 9.5_dp], &
        periodic=[.true., .true., .false.], want_position=.true., &
        masses_by_type=[1.0_dp, 1.0_dp, 1.0_dp], unit_length='Ang', unit_time='ps', &
        unit_energy='eV', unit_velocity='Ang ps-1', unit_mass='u', creator_version='test'), ok, msg)
    if (.not. ok) error stop 'h5md_killed: create failed'
    do k = 0, 1
        nl = 0
        do id = 1, n
            if (mod(id, nprocs) /= rank) cycle
            nl = nl + 1; ids(nl) = id; types(nl) = 1
            do d = 1, 3
                x(d, nl) = 10.0_dp*id + d + 0.25_dp*k
            end do
        end do
        call w%write_frame(int(k, i8), 0.5_dp*k, nl, ids, types, x=x, ok=ok, msg=msg)
        if (.not. ok) error stop 'h5md_killed: write_frame failed'
    end do
    call MPI_Barrier(MPI_COMM_WORLD)
    if (rank == 0) call MPI_Abort(MPI_COMM_WORLD, 3)
    call MPI_Barrier(MPI_COMM_WORLD)
end program h5md_killed
