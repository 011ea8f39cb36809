!> A built scene: what the run's assembly hands the engine (terrace_engine's setup): the box, the
!> atoms this rank owns, the domain, the potential, the plan and, for a restart, the checkpoint's
!> forces and named values. Built by terrace_scene_builder from the deck.
module terrace_scene
    use terrace_kinds, only: dp, i8
    use terrace_box, only: box_t
    use terrace_atoms, only: atoms_t
    use terrace_domain, only: domain_t
    use terrace_potential, only: potential_t
    use terrace_scene_plan, only: plan_t
    use terrace_named_values, only: named_values_t
    implicit none
    private

    type, public :: scene_t
        type(box_t) :: box
        type(atoms_t) :: atoms                   !< the atoms this rank owns (no ghosts yet)
        type(domain_t) :: dom                    !< set up for the potential's halo reach + skin
        class(potential_t), allocatable :: pot
        type(plan_t) :: plan
        integer(i8) :: natoms = 0
        real(dp) :: cutmax = 0                   !< the potential's largest cutoff (0: none)
        character(len=:), allocatable :: source  !< where the atoms came from (for messages)
        logical :: restarted = .false.           !< started from &system read_checkpoint
        type(named_values_t) :: restart_values    !< the checkpoint's named values (integrator state)
        real(dp), allocatable :: restart_f(:, :) !< the checkpoint's forces, (3, N) by id
        integer(i8), allocatable :: mesh_tet(:, :) !< a mesh scene: (4, ntet) node ids of the tetrahedra
        integer(i8) :: mesh_hash = 0             !< a mesh scene: fingerprint of its connectivity and reference
    end type scene_t

end module terrace_scene
