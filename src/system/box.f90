!> The simulation box: orthorhombic, periodic or free per dimension, in 2-D or 3-D.
!> In 2-D the z extent is a nominal [-0.5, 0.5] and the "volume" is the area.
module terrace_box
    use terrace_kinds, only: dp
    implicit none
    private

    type, public :: box_t
        integer :: dimension = 3
        real(dp) :: lo(3) = 0.0_dp, hi(3) = 1.0_dp, length(3) = 1.0_dp
        logical :: periodic(3) = .true.
    contains
        procedure :: volume => box_volume
        procedure :: set => box_set
    end type box_t

contains

    subroutine box_set(self, lo, hi, periodic, dimension)
        class(box_t), intent(inout) :: self
        real(dp), intent(in) :: lo(3), hi(3)
        logical, intent(in) :: periodic(3)
        integer, intent(in) :: dimension
        self%lo = lo; self%hi = hi; self%periodic = periodic; self%dimension = dimension
        if (dimension == 2) then
            self%lo(3) = -0.5_dp; self%hi(3) = 0.5_dp; self%periodic(3) = .true.
        end if
        self%length = self%hi - self%lo
    end subroutine box_set

    pure real(dp) function box_volume(self)
        class(box_t), intent(in) :: self
        box_volume = product(self%length(1:self%dimension))
    end function box_volume

end module terrace_box
