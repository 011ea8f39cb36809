!> Growing allocatable arrays, for buffers that are reused from call to call.
!>
!> reserve(a, n): a has room for at least n entries. When it has to grow, its contents are lost
!> and its new size is max(n + n/4, minimum) (25 % headroom, so that a size that creeps up by a
!> few entries does not reallocate every time); with zero = .true. the new array is zero-filled.
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

    subroutine reserve_int(a, n, minimum, zero)
        integer, allocatable, intent(inout) :: a(:)
        integer, intent(in) :: n
        integer, intent(in), optional :: minimum
        logical, intent(in), optional :: zero
        if (allocated(a)) then
            if (size(a) >= n) return
            deallocate (a)
        end if
        allocate (a(new_size(n, minimum)))
        if (present(zero)) then
            if (zero) a = 0
        end if
    end subroutine reserve_int

    subroutine reserve_real(a, n, minimum, zero)
        real(dp), allocatable, intent(inout) :: a(:)
        integer, intent(in) :: n
        integer, intent(in), optional :: minimum
        logical, intent(in), optional :: zero
        if (allocated(a)) then
            if (size(a) >= n) return
            deallocate (a)
        end if
        allocate (a(new_size(n, minimum)))
        if (present(zero)) then
            if (zero) a = 0
        end if
    end subroutine reserve_real

    pure integer function new_size(n, minimum) result(m)
        integer, intent(in) :: n
        integer, intent(in), optional :: minimum
        m = n + n/4
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
        integer, intent(in) :: keep, n
        integer, allocatable :: t(:, :)
        allocate (t(size(a, 1), max(n, size(a, 2) + size(a, 2)/4)))
        t(:, 1:keep) = a(:, 1:keep)
        call move_alloc(t, a)
    end subroutine grow_keep_int2

    subroutine grow_keep_real2(a, keep, n)
        real(dp), allocatable, intent(inout) :: a(:, :)
        integer, intent(in) :: keep, n
        real(dp), allocatable :: t(:, :)
        allocate (t(size(a, 1), max(n, size(a, 2) + size(a, 2)/4)))
        t(:, 1:keep) = a(:, 1:keep)
        call move_alloc(t, a)
    end subroutine grow_keep_real2

end module terrace_grow
