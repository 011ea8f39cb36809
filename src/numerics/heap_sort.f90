!> Heap sort of an index array by 64-bit keys (no recursion, no scratch): gather_by_id's order of
!> atoms, the node-to-face contact's candidate keys.
module terrace_heap_sort
    use terrace_kinds, only: i8
    implicit none
    private

    public :: sort_by_id

contains

    !> order(:) permuted so that ids(order(:)) ascends (order holds indices into ids).
    subroutine sort_by_id(ids, order)
        integer(i8), intent(in) :: ids(:)
        integer, intent(inout) :: order(:)
        integer :: n, i, tmp
        n = size(order)
        do i = n/2, 1, -1
            call sift(i, n)
        end do
        do i = n, 2, -1
            tmp = order(1); order(1) = order(i); order(i) = tmp
            call sift(1, i - 1)
        end do
    contains
        subroutine sift(start, last)
            integer, intent(in) :: start, last
            integer :: root, child, t
            root = start
            do while (2*root <= last)
                child = 2*root
                if (child < last) then
                    if (ids(order(child + 1)) > ids(order(child))) child = child + 1
                end if
                if (ids(order(root)) >= ids(order(child))) return
                t = order(root); order(root) = order(child); order(child) = t
                root = child
            end do
        end subroutine sift
    end subroutine sort_by_id

end module terrace_heap_sort
