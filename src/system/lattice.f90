!> Lattice scenes: fcc, bcc, sc (3-D) and hex, sq (2-D), cells(1) x cells(2) [x cells(3)] unit
!> cells of edge a (from lattice_constant, or from a number density: a = (n_basis/rho)^(1/d) for
!> the cubic cells; hex has a rectangular cell a x a sqrt(3) with 2 atoms). Each rank creates only
!> the sites it owns; ids are global and independent of the rank count.
module terrace_lattice
    use terrace_kinds, only: dp, i8
    implicit none
    private

    public :: lattice_basis, lattice_cell

contains

    !> Fractional basis positions of the unit cell.
    subroutine lattice_basis(name, basis)
        character(len=*), intent(in) :: name
        real(dp), allocatable, intent(out) :: basis(:, :)
        select case (name)
        case ('fcc')
            allocate (basis(3, 4))
            basis = reshape([0.0_dp, 0.0_dp, 0.0_dp, 0.5_dp, 0.5_dp, 0.0_dp, &
                             0.5_dp, 0.0_dp, 0.5_dp, 0.0_dp, 0.5_dp, 0.5_dp], [3, 4])
        case ('bcc')
            allocate (basis(3, 2))
            basis = reshape([0.0_dp, 0.0_dp, 0.0_dp, 0.5_dp, 0.5_dp, 0.5_dp], [3, 2])
        case ('hex')
            allocate (basis(3, 2))
            basis = reshape([0.0_dp, 0.0_dp, 0.0_dp, 0.5_dp, 0.5_dp, 0.0_dp], [3, 2])
        case default   ! sc, sq
            allocate (basis(3, 1))
            basis = 0
        end select
    end subroutine lattice_basis

    !> Edge lengths of the unit cell.
    function lattice_cell(name, lattice_constant, density, dimension) result(cell)
        character(len=*), intent(in) :: name
        real(dp), intent(in) :: lattice_constant, density
        integer, intent(in) :: dimension
        real(dp) :: cell(3), a
        real(dp), allocatable :: basis(:, :)
        call lattice_basis(name, basis)
        if (lattice_constant > 0) then
            a = lattice_constant
        else if (name == 'hex') then
            a = sqrt(2.0_dp/(sqrt(3.0_dp)*density))
        else
            a = (size(basis, 2)/density)**(1.0_dp/dimension)
        end if
        cell = a
        if (name == 'hex') cell(2) = a*sqrt(3.0_dp)
        if (dimension == 2) cell(3) = 1
    end function lattice_cell

end module terrace_lattice
