!> The scene plan: what this run will compute and what it skips (decided once from the deck and the
!> atom count by terrace_scene_planner), printed by `terrace --check` and at the start of a run.
module terrace_scene_plan
    use terrace_kinds, only: i8
    implicit none
    private

    !> pair_all: no list, every owned atom meets every atom (small free scenes, cutoff-free LJ);
    !> pair_cells: cell lists + half Verlet list; pair_none: no pair list at all (terms with fixed
    !> partners, such as the elements of one mesh), only the halo.
    integer, parameter, public :: pair_all = 1, pair_cells = 2, pair_none = 3

    type, public :: plan_t
        integer(i8) :: natoms = 0
        integer :: nprocs = 1
        integer :: dims(3) = 1
        integer :: pair_mode = pair_cells
        integer(i8) :: all_pairs_max = 64    !< 'auto' picks all pairs up to this many atoms (free scenes)
        !> energy stepping: force and ray passes over a pruned copy of the list (pairs within
        !> rc + skin/4, pruned again when an atom has moved skin/8), for potentials whose passes
        !> allow it (runs_on_pruned_list: Lennard-Jones). Only with cell lists, and not where the
        !> passes need the complement list (want_below: EAM). Velocity Verlet with &neighbor
        !> outer_skin: the force pass over the pairs within rc + skin pruned from the list built
        !> with outer_skin (terrace_engine, engine_list_due).
        logical :: inner_list = .false.
        !> Cluster-pair list in place of the atom list (terrace_cluster_list): the potential wants one
        !> (the mixed-precision LJ kernel), 3-D, cell lists, &neighbor list = 'auto' or 'clusters'
        logical :: cluster_pairs = .false.
        !> One rank, a box periodic in all three dimensions and more than twice the list's cutoff wide,
        !> a force pass that reads wrapped images (potential%wraps_images), velocity Verlet or a
        !> minimizer without the virial's diagonal, &neighbor images = 'auto': the periodic images are
        !> copied at each list build only, and the force pass reads each as its owner at the nearest
        !> image (terrace_engine, wrapped images: the engine checks the box again at each build)
        logical :: wrap_images = .false.
        !> One rank in 3-D, &neighbor images = 'auto', and a half list the only reader of the ghosts
        !> (the engine's ghosts_below): the halo holds half the periodic images (terrace_domain's
        !> half_images; the engine checks the box at each build)
        logical :: half_images = .false.
        logical :: mesh = .false.            !< the atoms are a mesh's nodes (&system mesh_file)
        character(len=:), allocatable :: halo, pairs, potential, integrator, outputs, box
    contains
        procedure :: print => plan_print
    end type plan_t

contains

    subroutine plan_print(self, unit)
        class(plan_t), intent(in) :: self
        integer, intent(in) :: unit
        character(len=:), allocatable :: what
        what = ' atoms on '
        if (self%mesh) what = ' mesh nodes on '
        write (unit, '(a,i0,a,i0,a,i0,a,i0,a,i0,a)') 'scene plan: ', self%natoms, what, self%nprocs, &
            ' rank(s), grid ', self%dims(1), ' x ', self%dims(2), ' x ', self%dims(3)
        write (unit, '(a)') '  box        : '//self%box
        write (unit, '(a)') '  pairs      : '//self%pairs
        write (unit, '(a)') '  halo       : '//self%halo
        write (unit, '(a)') '  potential  : '//self%potential
        write (unit, '(a)') '  integrator : '//self%integrator
        write (unit, '(a)') '  outputs    : '//self%outputs
    end subroutine plan_print

end module terrace_scene_plan
