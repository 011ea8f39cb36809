!> The &potential styles as data: each style's name, the &potential keys of its own and what it
!> is (pair, many-body, mesh or stepped; smooth at its cutoff or not; what it needs: a file, element
!> names, a mesh, metal units). The deck reader checks keys and combinations through these records
!> and never compares a style name; the potential factory (run/potential_factory.f90) maps a name
!> to its type. Adding a potential: one row in `potential_table` (and the case in the factory).
module terrace_potential_styles
    implicit none
    private

    !> What one &potential style is and takes.
    type, public :: potential_style_t
        character(len=24) :: name = ''              !< '' for a name no style has
        !> its own keys, separated by blanks (the keys every style takes, style and precision, are not listed)
        character(len=256) :: keys = ''
        logical :: pair = .false.                   !< a pair potential with per-type-pair coefficients in the deck
        logical :: many_body = .false.              !< energy not a sum over pairs (embedding terms)
        logical :: mesh = .false.                   !< elastic elements of a mesh: needs &system mesh_file
        logical :: stepped = .false.                !< steps in V(r): forces are impulses (event-driven dynamics)
        logical :: jumps_at_cutoff = .false.        !< V jumps at the cutoff unless shift = .true.
        logical :: no_cutoff = .false.              !< cutoff = 0 (every pair) allowed in a free scene
        logical :: mixed_precision = .false.        !< precision = 'mixed' (single-precision pairs) available
        logical :: needs_file = .false.             !< its tables come from &potential file
        logical :: needs_elements = .false.         !< the file holds several elements: &potential elements
        logical :: needs_metal_units = .false.      !< its file is in eV and Angstrom
        logical :: all_pairs = .true.               !< runs on the all-pairs path (&neighbor list = 'all_pairs')
        !> LAMMPS data files: the prefix of the pair styles whose Pair Coeffs section it reads ('': none)
        character(len=8) :: data_coeffs = ''
    end type potential_style_t

    character(len=*), parameter :: lj_keys = 'epsilon sigma cutoff pair_cutoff shift'
    character(len=*), parameter :: eam_keys = 'file elements'

    !> Every style, in the order the messages list them; row 0 stands for a name no style has.
    type(potential_style_t), parameter, public :: potential_table(0:8) = [potential_style_t(), &
        potential_style_t('lj', lj_keys, pair=.true., jumps_at_cutoff=.true., no_cutoff=.true., &
                          mixed_precision=.true., data_coeffs='lj'), &
        potential_style_t('lj/smooth/linear', lj_keys, pair=.true., data_coeffs='lj'), &
        potential_style_t('eam', eam_keys, many_body=.true., needs_file=.true., needs_metal_units=.true., &
                          all_pairs=.false.), &
        potential_style_t('eam/alloy', eam_keys, many_body=.true., needs_file=.true., needs_elements=.true., &
                          needs_metal_units=.true., all_pairs=.false.), &
        potential_style_t('eam/fs', eam_keys, many_body=.true., needs_file=.true., needs_elements=.true., &
                          needs_metal_units=.true., all_pairs=.false.), &
        potential_style_t('neohookean', 'lambda mu volume_lambda volume_mu contact_stiffness contact_distance '// &
                          'contact_model walls wall_planes wall_stiffness wall_distance', mesh=.true.), &
        potential_style_t('hard_sphere', 'diameter', pair=.true., stepped=.true.), &
        potential_style_t('square_well', 'diameter well_depth well_lambda well_radius', pair=.true., stepped=.true.)]

    !> The style of a deck without &potential style.
    character(len=*), parameter, public :: default_potential_style = 'lj'

end module terrace_potential_styles
