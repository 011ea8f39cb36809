!> The &minimize styles as data: each style's name and the &minimize keys it takes. The deck reader
!> checks the group through these records and never compares a style name; run_minimize
!> (minimize.f90) runs the named method. Adding a minimizer: one row in `minimize_table`.
module terrace_minimize_styles
    implicit none
    private

    !> What one &minimize style takes.
    type, public :: minimize_style_t
        character(len=8) :: name = ''               !< '' for a name no style has
        !> its keys, separated by blanks (style is every style's)
        character(len=72) :: keys = ''
    end type minimize_style_t

    character(len=*), parameter :: common_keys = 'etol ftol max_iterations max_evaluations box_relax pressure'

    !> Every style, in the order the messages list them; row 0 stands for a name no style has.
    type(minimize_style_t), parameter, public :: minimize_table(0:2) = [minimize_style_t(), &
        minimize_style_t('fire', common_keys), &
        minimize_style_t('cg', common_keys)]

end module terrace_minimize_styles
