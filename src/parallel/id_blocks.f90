!> Atoms in global id order without gathering them: ids 1..N are split into contiguous blocks, one
!> per rank (rank r holds ids first .. first+count-1), and every atom's values are sent to the rank
!> whose block holds its id with one MPI_Alltoallv; each rank then has its block in id order, ready
!> to be written as one hyperslab. The H5MD trajectory writer (src/io/h5md.f90) uses the same blocks.
module terrace_id_blocks
    use terrace_kinds, only: dp, i8
    use terrace_mpi_env, only: world, any_all
    use mpi_f08, only: MPI_Comm, MPI_Alltoall, MPI_Alltoallv, MPI_INTEGER, MPI_DOUBLE_PRECISION
    implicit none
    private

    public :: id_block, id_block_owner, to_id_blocks, exchange_plan

contains

    !> Block of ids 1..n held by rank r (0-based) of p.
    pure subroutine id_block(n, p, r, first, count)
        integer(i8), intent(in) :: n
        integer, intent(in) :: p, r
        integer(i8), intent(out) :: first, count
        integer(i8) :: q, rm
        q = n/p; rm = mod(n, int(p, i8))
        count = q + merge(1_i8, 0_i8, r < rm)
        first = r*q + min(int(r, i8), rm) + 1
    end subroutine id_block

    !> The rank (0-based) whose block holds id.
    pure integer function id_block_owner(id, n, p) result(r)
        integer(i8), intent(in) :: id, n
        integer, intent(in) :: p
        integer(i8) :: q, rm, k
        q = n/p; rm = mod(n, int(p, i8)); k = id - 1
        if (k < rm*(q + 1)) then
            r = int(k/(q + 1))
        else
            r = int(rm + (k - rm*(q + 1))/q)
        end if
    end function id_block_owner

    !> The exchange that sends every atom to the rank whose block holds its id (ranks 0..P-1 of
    !> comm): dest(i) is the rank of ids(i); scount(r) atoms go to rank r, from position sdisp(r)+1
    !> of a send buffer ordered by rank; rcount(r) come from rank r, to position rdisp(r)+1 of the
    !> receive buffer (one MPI_Alltoall; collective).
    subroutine exchange_plan(ids, natoms, comm, dest, scount, sdisp, rcount, rdisp)
        integer(i8), intent(in) :: ids(:), natoms
        type(MPI_Comm), intent(in) :: comm
        integer, intent(out) :: dest(:)
        integer, intent(out) :: scount(0:), sdisp(0:), rcount(0:), rdisp(0:)
        integer :: i, r, P
        P = size(scount)
        scount = 0
        do i = 1, size(ids)
            dest(i) = id_block_owner(ids(i), natoms, P)
            scount(dest(i)) = scount(dest(i)) + 1
        end do
        call MPI_Alltoall(scount, 1, MPI_INTEGER, rcount, 1, MPI_INTEGER, comm)
        sdisp(0) = 0; rdisp(0) = 0
        do r = 1, P - 1
            sdisp(r) = sdisp(r - 1) + scount(r - 1)
            rdisp(r) = rdisp(r - 1) + rcount(r - 1)
        end do
    end subroutine exchange_plan

    !> values(:, 1:nlocal) of this rank's atoms ids(1:nlocal) (every id 1..natoms exactly once over
    !> the ranks) -> block(:, 1:count), the values of ids first .. first+count-1 in id order.
    !> ok is .false. on every rank when an id is missing, repeated or out of range. Collective.
    subroutine to_id_blocks(natoms, nlocal, ids, values, first, count, block, ok)
        integer(i8), intent(in) :: natoms
        integer, intent(in) :: nlocal
        integer(i8), intent(in) :: ids(:)
        real(dp), intent(in) :: values(:, :)
        integer(i8), intent(out) :: first, count
        real(dp), allocatable, intent(out) :: block(:, :)
        logical, intent(out) :: ok
        integer, allocatable :: scount(:), rcount(:), sdisp(:), rdisp(:), cursor(:), dest(:)
        real(dp), allocatable :: sbuf(:, :), rbuf(:, :)
        logical, allocatable :: seen(:)
        integer :: nc, P, i, r, j, nrecv
        integer(i8) :: k
        logical :: bad
        nc = size(values, 1) + 1
        P = world%nprocs
        call id_block(natoms, P, world%rank, first, count)
        bad = .false.
        do i = 1, nlocal
            if (ids(i) < 1 .or. ids(i) > natoms) bad = .true.
        end do
        call any_all(bad)
        if (bad) then
            ok = .false.; allocate (block(nc - 1, 0)); return
        end if
        allocate (scount(0:P - 1), rcount(0:P - 1), sdisp(0:P - 1), rdisp(0:P - 1), dest(nlocal))
        call exchange_plan(ids(1:nlocal), natoms, world%comm, dest, scount, sdisp, rcount, rdisp)
        cursor = sdisp
        allocate (sbuf(nc, max(nlocal, 1)))
        do i = 1, nlocal
            r = dest(i)
            cursor(r) = cursor(r) + 1; j = cursor(r)
            sbuf(1, j) = real(ids(i), dp)
            sbuf(2:nc, j) = values(:, i)
        end do
        nrecv = sum(rcount)
        allocate (rbuf(nc, max(nrecv, 1)))
        call MPI_Alltoallv(sbuf, nc*scount, nc*sdisp, MPI_DOUBLE_PRECISION, rbuf, nc*rcount, nc*rdisp, &
                           MPI_DOUBLE_PRECISION, world%comm)
        allocate (block(nc - 1, max(count, 1_i8)), seen(max(count, 1_i8)))
        seen = .false.
        bad = nrecv /= count
        if (.not. bad) then
            do j = 1, nrecv
                k = nint(rbuf(1, j), i8) - first + 1
                if (k < 1 .or. k > count) then
                    bad = .true.; exit
                end if
                if (seen(k)) then
                    bad = .true.; exit
                end if
                seen(k) = .true.
                block(:, k) = rbuf(2:nc, j)
            end do
        end if
        call any_all(bad)
        ok = .not. bad
    end subroutine to_id_blocks

end module terrace_id_blocks
