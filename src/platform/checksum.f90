!> Order-independent checksums of per-atom tables (checksum.c): the sum modulo 2^64 of a mix of
!> (atom id, column, value bits) over every value, the same for any split of the rows over ranks.
!> Checkpoints store one per dataset and verify it on restart (doc/checkpoints.md).
module terrace_checksum
    use, intrinsic :: iso_c_binding, only: c_int32_t, c_int64_t, c_char, c_ptr
    use terrace_kinds, only: i8
    use terrace_mpi_env, only: world
    use mpi_f08, only: MPI_Allgather, MPI_INTEGER8
    implicit none
    private

    public :: checksum_rows, checksum_text, checksum_add, checksum_over_ranks

    interface
        integer(c_int64_t) function c_rows(first, count, ncol, elsize, data) bind(C, name='terrace_checksum_rows')
            import :: c_int64_t, c_int32_t, c_ptr
            integer(c_int64_t), value :: first, count
            integer(c_int32_t), value :: ncol, elsize
            type(c_ptr), value :: data
        end function c_rows
        integer(c_int64_t) function c_text(salt, n, s) bind(C, name='terrace_checksum_text')
            import :: c_int64_t, c_char
            integer(c_int64_t), value :: salt, n
            character(kind=c_char), intent(in) :: s(*)
        end function c_text
        integer(c_int64_t) function c_add(a, b) bind(C, name='terrace_checksum_add')
            import :: c_int64_t
            integer(c_int64_t), value :: a, b
        end function c_add
    end interface

contains

    !> Checksum of count rows (ids first..first+count-1), ncol values of elsize bytes each, at data.
    integer(i8) function checksum_rows(first, count, ncol, elsize, data)
        integer(i8), intent(in) :: first, count
        integer, intent(in) :: ncol, elsize
        type(c_ptr), intent(in) :: data
        checksum_rows = c_rows(first, count, int(ncol, c_int32_t), int(elsize, c_int32_t), data)
    end function checksum_rows

    integer(i8) function checksum_text(salt, s)
        integer(i8), intent(in) :: salt
        character(len=*), intent(in) :: s
        checksum_text = c_text(salt, int(len(s), c_int64_t), s)
    end function checksum_text

    integer(i8) function checksum_add(a, b)
        integer(i8), intent(in) :: a, b
        checksum_add = c_add(a, b)
    end function checksum_add

    !> The sum (modulo 2^64) of every rank's partial checksum. Collective.
    integer(i8) function checksum_over_ranks(partial) result(total)
        integer(i8), intent(in) :: partial
        integer(i8) :: all(world%nprocs)
        integer :: r
        call MPI_Allgather(partial, 1, MPI_INTEGER8, all, 1, MPI_INTEGER8, world%comm)
        total = 0
        do r = 1, world%nprocs
            total = checksum_add(total, all(r))
        end do
    end function checksum_over_ranks

end module terrace_checksum
