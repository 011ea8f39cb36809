!> Several potential terms added into one: V = sum_k V_k, so that forces, energies, virials and
!> the ray's (V, V', V'', W) are sums over the terms. A scene with one term (LJ, EAM) uses that term
!> directly; a mesh with contact between its bodies is the sum of the element term and the contact
!> term, and the engine and the integrators see one potential either way.
module terrace_potential_sum
    use terrace_kinds, only: dp
    use terrace_atoms, only: atoms_t
    use terrace_neighbor_list, only: neighbor_list_t
    use terrace_potential, only: potential_t, halo_ops_t, max_warning_flags
    implicit none
    private

    type :: term_t
        class(potential_t), allocatable :: p
    end type term_t

    type, extends(potential_t), public :: potential_sum_t
        type(term_t), allocatable :: terms(:)
    contains
        procedure :: add => sum_add
        procedure :: forces => sum_forces
        procedure :: ray => sum_ray
        procedure :: cutoff => sum_cutoff
        procedure :: describe => sum_describe
        procedure :: halo_reach => sum_halo_reach
        procedure :: needs_pair_list => sum_needs_pair_list
        procedure :: supports_all_pairs => sum_supports_all_pairs
        procedure :: needs_full_neighbourhood => sum_needs_full
        procedure :: runs_on_pruned_list => sum_runs_on_pruned_list
        procedure :: wants_neighbour_types => sum_wants_types
        procedure :: neighbour_type_order => sum_type_order
        procedure :: contact_distance => sum_contact_distance
        procedure :: time_unit => sum_time_unit
        procedure :: round_off_scale => sum_round_off_scale
        procedure :: cutoff_derivatives => sum_cutoff_derivatives
        procedure :: on_rebuild => sum_on_rebuild
        procedure :: preferred_skin => sum_preferred_skin
        procedure :: may_become_invalid => sum_may_become_invalid
        procedure :: invalid_state => sum_invalid_state
        procedure :: list_problem => sum_list_problem
    end type potential_sum_t

contains

    !> Append a term (moved in: term is deallocated on return).
    subroutine sum_add(self, term)
        class(potential_sum_t), intent(inout) :: self
        class(potential_t), allocatable, intent(inout) :: term
        type(term_t), allocatable :: grown(:)
        integer :: n, k
        n = 0
        if (allocated(self%terms)) n = size(self%terms)
        allocate (grown(n + 1))
        do k = 1, n
            call move_alloc(self%terms(k)%p, grown(k)%p)
        end do
        call move_alloc(term, grown(n + 1)%p)
        call move_alloc(grown, self%terms)
    end subroutine sum_add

    subroutine sum_forces(self, atoms, list, halo, want_energy, energy, virial)
        class(potential_sum_t), intent(inout) :: self
        include 'potential_forces_args.inc'
        real(dp) :: e, w
        integer :: k
        energy = 0; virial = 0
        do k = 1, size(self%terms)
            call self%terms(k)%p%forces(atoms, list, halo, want_energy, e, w)
            energy = energy + e; virial = virial + w
        end do
    end subroutine sum_forces

    subroutine sum_ray(self, atoms, list, s, out)
        class(potential_sum_t), intent(inout) :: self
        include 'potential_ray_args.inc'
        real(dp) :: part(4)
        integer :: k
        out = 0
        do k = 1, size(self%terms)
            call self%terms(k)%p%ray(atoms, list, s, part)
            out = out + part
        end do
    end subroutine sum_ray

    pure real(dp) function sum_cutoff(self)
        class(potential_sum_t), intent(in) :: self
        integer :: k
        sum_cutoff = max(0.0_dp, maxval([(self%terms(k)%p%cutoff(), k = 1, size(self%terms))]))
    end function sum_cutoff

    pure real(dp) function sum_halo_reach(self)
        class(potential_sum_t), intent(in) :: self
        integer :: k
        sum_halo_reach = max(0.0_dp, maxval([(self%terms(k)%p%halo_reach(), k = 1, size(self%terms))]))
    end function sum_halo_reach

    function sum_describe(self) result(text)
        class(potential_sum_t), intent(in) :: self
        character(len=:), allocatable :: text
        integer :: k
        text = 'sum of'
        do k = 1, size(self%terms)
            text = text//merge(' ', ';', k == 1)//' ['//self%terms(k)%p%describe()//']'
        end do
    end function sum_describe

    pure logical function sum_needs_pair_list(self)
        class(potential_sum_t), intent(in) :: self
        integer :: k
        sum_needs_pair_list = any([(self%terms(k)%p%needs_pair_list(), k = 1, size(self%terms))])
    end function sum_needs_pair_list

    pure logical function sum_supports_all_pairs(self)
        class(potential_sum_t), intent(in) :: self
        integer :: k
        sum_supports_all_pairs = all([(self%terms(k)%p%supports_all_pairs(), k = 1, size(self%terms))])
    end function sum_supports_all_pairs

    pure logical function sum_needs_full(self, energy_stepping)
        class(potential_sum_t), intent(in) :: self
        logical, intent(in) :: energy_stepping
        integer :: k
        sum_needs_full = any([(self%terms(k)%p%needs_full_neighbourhood(energy_stepping), k = 1, size(self%terms))])
    end function sum_needs_full

    pure logical function sum_wants_types(self)
        class(potential_sum_t), intent(in) :: self
        integer :: k
        sum_wants_types = any([(self%terms(k)%p%wants_neighbour_types(), k = 1, size(self%terms))])
    end function sum_wants_types

    pure integer function sum_type_order(self)
        class(potential_sum_t), intent(in) :: self
        integer :: k
        sum_type_order = maxval([(self%terms(k)%p%neighbour_type_order(), k = 1, size(self%terms))])
    end function sum_type_order

    pure logical function sum_runs_on_pruned_list(self)
        class(potential_sum_t), intent(in) :: self
        integer :: k
        sum_runs_on_pruned_list = all([(self%terms(k)%p%runs_on_pruned_list(), k = 1, size(self%terms))])
    end function sum_runs_on_pruned_list

    pure real(dp) function sum_contact_distance(self, ti, tj)
        class(potential_sum_t), intent(in) :: self
        integer, intent(in) :: ti, tj
        integer :: k
        sum_contact_distance = 0
        do k = 1, size(self%terms)
            sum_contact_distance = max(sum_contact_distance, self%terms(k)%p%contact_distance(ti, tj))
        end do
    end function sum_contact_distance

    !> The one term's (rc, V', V'', V''') at the cutoff; several terms: none (rc = 0, no estimate).
    pure function sum_cutoff_derivatives(self, ti, tj) result(d)
        class(potential_sum_t), intent(in) :: self
        integer, intent(in) :: ti, tj
        real(dp) :: d(4)
        d = 0
        if (size(self%terms) == 1) d = self%terms(1)%p%cutoff_derivatives(ti, tj)
    end function sum_cutoff_derivatives

    !> The shortest positive time unit of the terms, with its words (0 if none has one).
    pure subroutine sum_time_unit(self, mass, mvv2e, tau, words)
        class(potential_sum_t), intent(in) :: self
        real(dp), intent(in) :: mass, mvv2e
        real(dp), intent(out) :: tau
        character(len=:), allocatable, intent(out) :: words
        real(dp) :: t
        character(len=:), allocatable :: w
        integer :: k
        tau = 0
        words = ''
        do k = 1, size(self%terms)
            call self%terms(k)%p%time_unit(mass, mvv2e, t, w)
            if (t > 0 .and. (tau == 0 .or. t < tau)) then
                tau = t; words = w
            end if
        end do
    end subroutine sum_time_unit

    !> The terms' round-off scales added.
    pure real(dp) function sum_round_off_scale(self)
        class(potential_sum_t), intent(in) :: self
        integer :: k
        sum_round_off_scale = 0
        do k = 1, size(self%terms)
            sum_round_off_scale = sum_round_off_scale + self%terms(k)%p%round_off_scale()
        end do
    end function sum_round_off_scale

    subroutine sum_on_rebuild(self, atoms)
        class(potential_sum_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        integer :: k
        do k = 1, size(self%terms)
            call self%terms(k)%p%on_rebuild(atoms)
        end do
    end subroutine sum_on_rebuild

    !> The smallest positive preference of the terms (0 if none has one).
    pure real(dp) function sum_preferred_skin(self)
        class(potential_sum_t), intent(in) :: self
        real(dp) :: t
        integer :: k
        sum_preferred_skin = 0
        do k = 1, size(self%terms)
            t = self%terms(k)%p%preferred_skin()
            if (t > 0 .and. (sum_preferred_skin == 0 .or. t < sum_preferred_skin)) sum_preferred_skin = t
        end do
    end function sum_preferred_skin

    pure logical function sum_may_become_invalid(self)
        class(potential_sum_t), intent(in) :: self
        integer :: k
        sum_may_become_invalid = .false.
        do k = 1, size(self%terms)
            sum_may_become_invalid = sum_may_become_invalid .or. self%terms(k)%p%may_become_invalid()
        end do
    end function sum_may_become_invalid

    !> The first term's invalid state (the terms that may become invalid are asked in order).
    logical function sum_invalid_state(self, text) result(bad)
        class(potential_sum_t), intent(in) :: self
        character(len=*), intent(out) :: text
        bad = first_problem(self, .false., text)
    end function sum_invalid_state

    !> The first term's list problem (potential%list_problem).
    logical function sum_list_problem(self, text) result(bad)
        class(potential_sum_t), intent(in) :: self
        character(len=*), intent(out) :: text
        bad = first_problem(self, .true., text)
    end function sum_list_problem

    !> Ask the terms that may become invalid, in order, for an invalid state or (list) a list problem.
    logical function first_problem(self, list, text) result(bad)
        class(potential_sum_t), intent(in) :: self
        logical, intent(in) :: list
        character(len=*), intent(out) :: text
        integer :: k
        bad = .false.
        text = ''
        do k = 1, size(self%terms)
            if (.not. self%terms(k)%p%may_become_invalid()) cycle
            if (list) then
                bad = self%terms(k)%p%list_problem(text)
            else
                bad = self%terms(k)%p%invalid_state(text)
            end if
            if (bad) return
        end do
    end function first_problem

end module terrace_potential_sum
