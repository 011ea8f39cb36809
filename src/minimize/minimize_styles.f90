!> The &minimize styles as data: each style's name and the &minimize keys it takes. The deck reader
!> checks the group through these records and never compares a style name; run_minimize
!> (minimize.f90) runs the named method. Adding a minimizer: one row in `minimize_table`.
module terrace_minimize_styles
    implicit none
    private

    !> What one &minimize style takes.
    type, public :: minimize_style_t
        character(len=8) :: name = ''               !< '' for a name no style has
        !> its keys, each between blanks (style is every style's)
        character(len=72) :: keys = ''
    end type minimize_style_t

    character(len=*), parameter :: common_keys = ' etol ftol max_iterations max_evaluations box_relax pressure '

    !> Every style, in the order the messages list them.
    type(minimize_style_t), parameter, public :: minimize_table(2) = [ &
        minimize_style_t('fire', common_keys), &
        minimize_style_t('cg', common_keys)]

    public :: minimize_style, takes_minimize_key

contains

    !> The record of the named style; one with name '' for an unknown name.
    pure function minimize_style(name) result(s)
        character(len=*), intent(in) :: name
        type(minimize_style_t) :: s
        integer :: k
        k = findloc(minimize_table%name, name, dim=1)
        if (k > 0) s = minimize_table(k)
    end function minimize_style

    !> Whether style s takes &minimize key.
    elemental logical function takes_minimize_key(s, key)
        type(minimize_style_t), intent(in) :: s
        character(len=*), intent(in) :: key
        takes_minimize_key = index(s%keys, ' '//trim(key)//' ') > 0
    end function takes_minimize_key

end module terrace_minimize_styles
