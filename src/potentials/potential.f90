!> The potential interface. Every interaction term of the engine (pair potentials, EAM, finite
!> elements, contact) is a potential_t: the engine and both integrators see only this type, so a
!> new potential needs no change to them (doc/architecture.md, "Adding a potential").
!>
!> Two kernels, both over the atoms this rank holds (owned 1..nlocal, ghosts after them):
!>   forces: F_i = -dV/dx_i added into atoms%f (owned and ghost rows; the engine zeroes f before
!>           and sums ghost rows into their owners after), and, when asked, this rank's share of
!>           V and of the virial W = sum_i x_i . F_i.
!>   ray:    this rank's share of V(x + s v), dV/ds, d2V/ds2 and W along the straight line every
!>           atom follows between energy-stepping events (ghosts carry velocities, so no message
!>           is needed; the engine sums the four numbers over ranks).
!> A many-body term that needs per-atom fields completed across ranks between its passes (EAM:
!> the densities summed into their owners, F'(rho) copied to the ghosts) asks the halo_ops_t the
!> engine hands it. Potentials hold no MPI: the engine owns the domain and the communication.
!>
!> The virial tensor's diagonal (virial_diagonal): W_aa = sum_i x_ai F_ai over the owned and ghost
!> rows after a force pass, before the ghost rows are summed into their owners. Every force a pass
!> adds acts between rows it holds (F_ij on i, -F_ij on the row of the image of j it used), so the
!> sum is sum over pairs of (x_i - x_j)_a (F_ij)_a, the virial of every term whatever its kernel;
!> a many-body term (EAM) adds its forces by pairs too. W_xx + W_yy + W_zz is the scalar virial.
module terrace_potential
    use terrace_kinds, only: dp
    use terrace_atoms, only: atoms_t
    use terrace_neighbor_list, only: neighbor_list_t
    implicit none
    private

    integer, parameter, public :: max_warning_flags = 8

    public :: virial_diagonal

    !> Per-atom field exchange between passes of a many-body potential, implemented by the engine.
    !> buf(ncomp, nall): reverse_sum adds each ghost row into its owner's row; forward copies each
    !> owner's row to its ghosts.
    type, abstract, public :: halo_ops_t
    contains
        procedure(halo_op), deferred :: reverse_sum
        procedure(halo_op), deferred :: forward
    end type halo_ops_t

    type, abstract, public :: potential_t
    contains
        procedure(forces_op), deferred :: forces
        procedure(ray_op), deferred :: ray
        procedure(real_query), deferred :: cutoff
        procedure(text_query), deferred :: describe
        procedure :: halo_reach => potential_halo_reach
        procedure :: needs_pair_list => potential_needs_pair_list
        procedure :: supports_all_pairs => potential_false
        !> .true.: the passes of this integrator need each owned atom's whole neighbourhood (the
        !> list's complement of ghosts below, list%below): EAM's ray pass, node-face contact always
        procedure :: needs_full_neighbourhood => potential_needs_full
        !> .true.: the force and ray passes are exact over any pair list that holds every pair
        !> within the cutoff (they use neither the list's skin nor its complement), so that energy
        !> stepping may run them over a pruned copy of the list (scene plan: inner_list)
        procedure :: runs_on_pruned_list => potential_false
        !> .true.: the passes read each neighbour's type from the list (list%want_types: a row
        !> filled at each build instead of a gather at every pass); multi-type Lennard-Jones
        procedure :: wants_neighbour_types => potential_false
        !> .true.: the force pass of a 3-D Verlet run can read a cluster-pair list (list%clusters,
        !> list%want_clusters) instead of the atom rows (&neighbor list = 'clusters'); the
        !> mixed-precision Lennard-Jones kernel
        procedure :: wants_clusters => potential_false
        !> .true.: the force pass can read a list with wrapped images (list%wrapped: each ghost read as
        !> its owner at the nearest periodic image), leaving the ghosts' positions unread and their
        !> forces untouched; the mixed-precision Lennard-Jones pass with AVX-512
        procedure :: wraps_images => potential_false
        !> > 1: the passes want each list row ordered by the neighbours' types 1..this
        !> (list%type_order: segments per type; multi-type EAM); 0: any order
        procedure :: neighbour_type_order => potential_type_order
        procedure :: contact_distance => potential_contact_distance
        procedure :: time_unit => potential_time_unit
        !> An energy E_r of the whole system (all ranks) whose 64 eps bounds the round-off of V where
        !> its terms cancel (a stiff element near its rest shape: W = mu/2 (|F|^2 - 3) - ...); 0: the
        !> round-off is that of |V| itself. The event search's tolerance is not set finer.
        procedure :: round_off_scale => potential_round_off_scale
        procedure :: preferred_skin => potential_preferred_skin
        !> (rc, V'(rc), V''(rc), V'''(rc)) of the pair term between types ti and tj (as the passes
        !> compute it: shifted or smoothed), for the Verlet buffer estimate; rc = 0: the term is not
        !> a pair potential with a cutoff (no estimate)
        procedure :: cutoff_derivatives => potential_cutoff_derivatives
        procedure :: warning_flags => potential_warning_flags
        procedure :: warning => potential_warning
        procedure :: on_rebuild => potential_on_rebuild
        procedure :: may_become_invalid => potential_false
        !> .true.: forces' energies and ray sums come back already summed over the ranks (the
        !> potential reduces them itself, e.g. exactly); the engine then does not sum them again
        procedure :: sums_global => potential_false
        procedure :: invalid_state => potential_invalid_state
        procedure :: list_problem => potential_invalid_state
    end type potential_t

    abstract interface
        subroutine halo_op(self, buf)
            import :: halo_ops_t, dp
            class(halo_ops_t), intent(inout) :: self
            real(dp), intent(inout) :: buf(:, :)
        end subroutine halo_op

        !> Forces added into atoms%f; energy and virial: this rank's shares (0 unless want_energy,
        !> for potentials whose force-only path skips them).
        subroutine forces_op(self, atoms, list, halo, want_energy, energy, virial)
            import :: potential_t, atoms_t, neighbor_list_t, halo_ops_t, dp
            class(potential_t), intent(inout) :: self
            include 'potential_forces_args.inc'
        end subroutine forces_op

        !> out = this rank's (V, dV/ds, d2V/ds2, W) at x + s v.
        subroutine ray_op(self, atoms, list, s, out)
            import :: potential_t, atoms_t, neighbor_list_t, dp
            class(potential_t), intent(inout) :: self
            include 'potential_ray_args.inc'
        end subroutine ray_op

        !> The largest pair distance at which the term acts (0: no cutoff, or no pairs).
        pure real(dp) function real_query(self)
            import :: potential_t, dp
            class(potential_t), intent(in) :: self
        end function real_query

        !> One line for the scene plan: the style, its parameters, what is computed and skipped.
        function text_query(self) result(text)
            import :: potential_t
            class(potential_t), intent(in) :: self
            character(len=:), allocatable :: text
        end function text_query
    end interface

contains

    !> (W_xx, W_yy, W_zz) = sum over rows 1..n of x_a f_a: the diagonal of the virial of the forces
    !> in f, when f holds the pass's forces on owned and ghost rows before the reverse sum. (One
    !> pass over contiguous rows, only when the diagonal is asked for.)
    pure function virial_diagonal(x, f, n) result(w)
        integer, intent(in) :: n
        real(dp), intent(in) :: x(:, :), f(:, :)
        real(dp) :: w(3)
        integer :: i
        w = 0
        do i = 1, n
            w = w + x(:, i)*f(:, i)
        end do
    end function virial_diagonal

    !> How far beyond its sub-domain a rank needs ghost atoms (without the neighbour skin): the
    !> cutoff for pair terms; a mesh returns its largest element extent.
    pure real(dp) function potential_halo_reach(self)
        class(potential_t), intent(in) :: self
        potential_halo_reach = self%cutoff()
    end function potential_halo_reach

    !> Whether the term walks the half neighbour list (a one-body mesh does not).
    pure logical function potential_needs_pair_list(self)
        class(potential_t), intent(in) :: self
        potential_needs_pair_list = .true.
    end function potential_needs_pair_list

    pure logical function potential_needs_full(self, energy_stepping)
        class(potential_t), intent(in) :: self
        logical, intent(in) :: energy_stepping
        potential_needs_full = .false.
    end function potential_needs_full

    pure logical function potential_false(self)
        class(potential_t), intent(in) :: self
        potential_false = .false.
    end function potential_false

    pure integer function potential_type_order(self)
        class(potential_t), intent(in) :: self
        potential_type_order = 0
    end function potential_type_order

    !> Distance below which two atoms of types ti and tj count as overlapping at the start (the
    !> run is refused below a quarter of it); 0: no overlap check for this pair.
    pure real(dp) function potential_contact_distance(self, ti, tj)
        class(potential_t), intent(in) :: self
        integer, intent(in) :: ti, tj
        potential_contact_distance = 0
    end function potential_contact_distance

    !> A natural time unit tau of the term for atoms of mass m (sigma sqrt(m/eps) for LJ), used by
    !> the estimates printed before a run, which give 0.005 tau as a stable Verlet step, and what
    !> that step is in words; tau = 0: none, the engine uses the curvature instead.
    pure subroutine potential_time_unit(self, mass, mvv2e, tau, words)
        class(potential_t), intent(in) :: self
        real(dp), intent(in) :: mass, mvv2e
        real(dp), intent(out) :: tau
        character(len=:), allocatable, intent(out) :: words
        tau = 0
        words = ''
    end subroutine potential_time_unit

    pure real(dp) function potential_round_off_scale(self)
        class(potential_t), intent(in) :: self
        potential_round_off_scale = 0
    end function potential_round_off_scale

    !> The neighbour-list skin the term wants when the deck gives none (a length natural to the
    !> term, such as a fraction of a contact distance); 0: no preference (the units' default).
    pure real(dp) function potential_preferred_skin(self)
        class(potential_t), intent(in) :: self
        potential_preferred_skin = 0
    end function potential_preferred_skin

    pure function potential_cutoff_derivatives(self, ti, tj) result(d)
        class(potential_t), intent(in) :: self
        integer, intent(in) :: ti, tj
        real(dp) :: d(4)
        d = 0
    end function potential_cutoff_derivatives

    !> This rank's sticky warning conditions (the engine ORs them over ranks).
    pure function potential_warning_flags(self) result(flags)
        class(potential_t), intent(in) :: self
        logical :: flags(max_warning_flags)
        flags = .false.
    end function potential_warning_flags

    !> A warning to print once (by rank 0), given the flags ORed over all ranks; .false.: none.
    logical function potential_warning(self, global_flags, text) result(have)
        class(potential_t), intent(inout) :: self
        logical, intent(in) :: global_flags(max_warning_flags)
        character(len=*), intent(out) :: text
        have = .false.
        text = ''
    end function potential_warning

    !> Called after every rebuild (migration, halo, list): local indices have changed.
    subroutine potential_on_rebuild(self, atoms)
        class(potential_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
    end subroutine potential_on_rebuild

    !> list_problem: after a force or ray pass, .true. with a description when this rank's pass could
    !> not serve the state from its list (node-to-face contact: a boundary edge stretched beyond the
    !> search's reach); every integrator stops there. Asked of the same potentials.
    !> After a force pass: .true. with a description when this rank's state has no finite energy
    !> (an inverted element); integrators with fixed steps stop there. Only asked of potentials whose
    !> may_become_invalid() is .true.
    logical function potential_invalid_state(self, text) result(bad)
        class(potential_t), intent(in) :: self
        character(len=*), intent(out) :: text
        bad = .false.
        text = ''
    end function potential_invalid_state

end module terrace_potential
