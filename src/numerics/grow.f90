!> Growing allocatable arrays, for buffers that are reused from call to call.
!>
!> reserve(a, n): a has room for at least n entries. When it has to grow, its contents are lost
!> and its new size is max(n + n/4, minimum) (25 % headroom, so that a size that creeps up by a
!> few entries does not reallocate every time); with zero = .true. the new array is zero-filled;
!> with exact = .true. its new size is max(n, minimum) (a caller that has sized n with its own margin).
!> grow_keep(a, keep, n): a grows to at least n entries (at least 25 % more than it had) keeping
!> its first `keep` entries (for a rank-2 array: its first `keep` columns).
!> Neither is meant for a hot loop: call them before one, with the loop's largest index.
module terrace_grow
    use terrace_kinds, only: dp
    implicit none
    private

    public :: reserve, grow_keep

    interface reserve
        module procedure reserve_int, reserve_real
    end interface reserve

    interface grow_keep
        module procedure grow_keep_int, grow_keep_int2, grow_keep_real2
    end interface grow_keep

contains

    ! The type-specific routines differ only in the declaration of `a` (and of `t`): the rest of
    ! each is one body, kept once in grow_reserve.inc / grow_keep2.inc and included by each.

    subroutine reserve_int(a, n, minimum, zero, exact)
        integer, allocatable, intent(inout) :: a(:)
        include 'grow_reserve.inc'
    end subroutine reserve_int

    subroutine reserve_real(a, n, minimum, zero, exact)
        real(dp), allocatable, intent(inout) :: a(:)
        include 'grow_reserve.inc'
    end subroutine reserve_real

    pure integer function new_size(n, minimum, exact) result(m)
        integer, intent(in) :: n
        integer, intent(in), optional :: minimum
        logical, intent(in), optional :: exact
        m = n + n/4
        if (present(exact)) then
            if (exact) m = n
        end if
        if (present(minimum)) m = max(m, minimum)
    end function new_size

    subroutine grow_keep_int(a, keep, n)
        integer, allocatable, intent(inout) :: a(:)
        integer, intent(in) :: keep, n
        integer, allocatable :: t(:)
        allocate (t(max(n, size(a) + size(a)/4)))
        t(1:keep) = a(1:keep)
        call move_alloc(t, a)
    end subroutine grow_keep_int

    subroutine grow_keep_int2(a, keep, n)
        integer, allocatable, intent(inout) :: a(:, :)
        integer, allocatable :: t(:, :)
        include 'grow_keep2.inc'
    end subroutine grow_keep_int2

    subroutine grow_keep_real2(a, keep, n)
        real(dp), allocatable, intent(inout) :: a(:, :)
        real(dp), allocatable :: t(:, :)
        include 'grow_keep2.inc'
    end subroutine grow_keep_real2

end module terrace_grow
