!> A stepped pair potential as a potential_t, so that the scene builder, the engine and the
!> plan treat it as any pair term (cutoff = the largest radius, overlap check at the hard core).
!> Its forces are impulses at the steps, which only the event-driven integrator applies
!> (terrace_event_driven); the force pass returns no forces, and the energy of the pairs within the
!> list (each pair's region energy), and the ray pass zeros: config refuses the other integrators.
module terrace_stepped_potential
    use terrace_kinds, only: dp
    use terrace_atoms, only: atoms_t
    use terrace_neighbor_list, only: neighbor_list_t
    use terrace_potential, only: potential_t, halo_ops_t
    use terrace_stepped_pair, only: stepped_table_t
    implicit none
    private

    type, extends(potential_t), public :: stepped_potential_t
        type(stepped_table_t) :: table
        character(len=:), allocatable :: style
    contains
        procedure :: forces => sp_forces
        procedure :: ray => sp_ray
        procedure :: cutoff => sp_cutoff
        procedure :: describe => sp_describe
        procedure :: contact_distance => sp_contact_distance
    end type stepped_potential_t

    public :: stepped_table_of

contains

    subroutine sp_forces(self, atoms, list, halo, want_energy, energy, virial)
        class(stepped_potential_t), intent(inout) :: self
        include 'potential_forces_args.inc'
        integer :: i, j, k, s
        real(dp) :: rsq
        energy = 0; virial = 0
        if (.not. want_energy .or. .not. self%table%has_steps) return
        if (.not. allocated(list%first)) return
        do i = 1, atoms%nlocal
            do k = list%first(i), list%first(i + 1) - 1
                j = list%neigh(k)
                rsq = sum((atoms%x(:, i) - atoms%x(:, j))**2)
                s = self%table%region_of(atoms%type(i), atoms%type(j), rsq)
                if (s > 0 .and. s < self%table%nr(atoms%type(i), atoms%type(j))) &
                    energy = energy + self%table%u(s, atoms%type(i), atoms%type(j))
            end do
        end do
    end subroutine sp_forces

    subroutine sp_ray(self, atoms, list, s, out)
        class(stepped_potential_t), intent(inout) :: self
        include 'potential_ray_args.inc'
        out = 0
    end subroutine sp_ray

    pure real(dp) function sp_cutoff(self)
        class(stepped_potential_t), intent(in) :: self
        sp_cutoff = self%table%rmax
    end function sp_cutoff

    function sp_describe(self) result(text)
        class(stepped_potential_t), intent(in) :: self
        character(len=:), allocatable :: text
        character(len=200) :: s
        write (s, '(a,i0,a,g0.6,a)') trim(self%style)//', ', self%table%ntypes, ' type(s), largest radius ', &
            self%table%rmax, '; impulses at the steps (event-driven integration)'
        text = trim(s)
    end function sp_describe

    !> The hard-core diameter of the pair.
    pure real(dp) function sp_contact_distance(self, ti, tj)
        class(stepped_potential_t), intent(in) :: self
        integer, intent(in) :: ti, tj
        sp_contact_distance = self%table%r(self%table%nr(ti, tj), ti, tj)
    end function sp_contact_distance

    !> The step table of pot when it is a stepped potential (found), for the event-driven loop.
    subroutine stepped_table_of(pot, table, found)
        class(potential_t), intent(in) :: pot
        type(stepped_table_t), intent(out) :: table
        logical, intent(out) :: found
        found = .false.
        select type (pot)
        type is (stepped_potential_t)
            table = pot%table
            found = .true.
        end select
    end subroutine stepped_table_of

end module terrace_stepped_potential
