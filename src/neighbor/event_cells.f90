!> The cell grid of event-driven dynamics: a periodic box cut into nc(1) x nc(2) x nc(3) cells of
!> at least the largest interaction radius (so that every interacting pair sits in neighbouring
!> cells, 27 of them), each a doubly linked list of its atoms, and each atom's cell coordinates.
!> An atom changes cell only at its cell-crossing event (move), never by recomputing the cell from
!> its position: the grid stays consistent whatever the round-off of the positions.
module terrace_event_cells
    use terrace_kinds, only: dp
    implicit none
    private

    type, public :: event_cells_t
        integer :: nc(3) = 0
        real(dp) :: lo(3) = 0, length(3) = 0, w(3) = 0
        integer, allocatable :: head(:)       !< (cell) first atom, 0: empty
        integer, allocatable :: nxt(:), prv(:) !< (atom) next / previous atom of its cell, 0: none
        integer, allocatable :: ic(:, :)       !< (3, atom) cell coordinates, 0 .. nc - 1
    contains
        procedure :: init => cells_init
        procedure :: index => cells_index
        procedure :: insert => cells_insert
        procedure :: remove => cells_remove
        procedure :: crossing => cells_crossing
    end type event_cells_t

contains

    !> A grid over the box [lo, lo + length) with cells of at least rmin; ok = .false. when the box
    !> holds fewer than 3 cells along a direction (the 27 neighbour cells would repeat).
    subroutine cells_init(self, lo, length, rmin, natoms, ok)
        class(event_cells_t), intent(inout) :: self
        real(dp), intent(in) :: lo(3), length(3), rmin
        integer, intent(in) :: natoms
        logical, intent(out) :: ok
        integer :: d
        self%lo = lo; self%length = length
        do d = 1, 3
            self%nc(d) = max(1, int(length(d)/rmin))
            ! no more cells than needed for about one atom each (memory for dilute scenes)
            self%nc(d) = min(self%nc(d), max(3, ceiling(2*real(natoms, dp)**(1.0_dp/3))))
            self%w(d) = length(d)/self%nc(d)
        end do
        ok = all(self%nc >= 3)
        if (allocated(self%head)) deallocate (self%head, self%nxt, self%prv, self%ic)
        allocate (self%head(product(self%nc)), self%nxt(natoms), self%prv(natoms), self%ic(3, natoms))
        self%head = 0; self%nxt = 0; self%prv = 0; self%ic = 0
    end subroutine cells_init

    pure integer function cells_index(self, c) result(k)
        class(event_cells_t), intent(in) :: self
        integer, intent(in) :: c(3)
        k = 1 + c(1) + self%nc(1)*(c(2) + self%nc(2)*c(3))
    end function cells_index

    !> Put atom i into cell c.
    subroutine cells_insert(self, i, c)
        class(event_cells_t), intent(inout) :: self
        integer, intent(in) :: i, c(3)
        integer :: k
        k = self%index(c)
        self%ic(:, i) = c
        self%prv(i) = 0
        self%nxt(i) = self%head(k)
        if (self%head(k) > 0) self%prv(self%head(k)) = i
        self%head(k) = i
    end subroutine cells_insert

    subroutine cells_remove(self, i)
        class(event_cells_t), intent(inout) :: self
        integer, intent(in) :: i
        if (self%prv(i) > 0) then
            self%nxt(self%prv(i)) = self%nxt(i)
        else
            self%head(self%index(self%ic(:, i))) = self%nxt(i)
        end if
        if (self%nxt(i) > 0) self%prv(self%nxt(i)) = self%prv(i)
        self%nxt(i) = 0; self%prv(i) = 0
    end subroutine cells_remove

    !> Time until the atom at x with velocity v leaves its cell, and through which face
    !> (dir = +d or -d for direction d).
    pure subroutine cells_crossing(self, i, x, v, dt, dir)
        class(event_cells_t), intent(in) :: self
        integer, intent(in) :: i
        real(dp), intent(in) :: x(3), v(3)
        real(dp), intent(out) :: dt
        integer, intent(out) :: dir
        real(dp) :: s
        integer :: d
        dt = huge(1.0_dp); dir = 0
        do d = 1, 3
            if (v(d) > 0) then
                s = (self%lo(d) + (self%ic(d, i) + 1)*self%w(d) - x(d))/v(d)
                if (s < dt) then
                    dt = s; dir = d
                end if
            else if (v(d) < 0) then
                s = (self%lo(d) + self%ic(d, i)*self%w(d) - x(d))/v(d)
                if (s < dt) then
                    dt = s; dir = -d
                end if
            end if
        end do
        dt = max(dt, 0.0_dp)
    end subroutine cells_crossing

end module terrace_event_cells
