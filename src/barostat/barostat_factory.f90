!> The one place that maps a &barostat style name to its type. Adding a barostat: a new file with
!> a type extending barostat_t, and one line in each list below.
module terrace_barostat_factory
    use terrace_barostat, only: barostat_t, barostat_params_t, barostat_none_t
    use terrace_barostat_c_rescale, only: c_rescale_t
    use terrace_barostat_mc, only: mc_barostat_t
    use terrace_barostat_mttk, only: mttk_t
    implicit none
    private

    !> The style names, for messages ("allowed: ...").
    character(len=*), parameter, public :: barostat_style_list = "'none', 'c_rescale', 'mc', 'mttk'"

    public :: new_barostat

contains

    !> A barostat of the named style, set up from p ('none' and unknown names: no barostat).
    subroutine new_barostat(name, p, bs)
        character(len=*), intent(in) :: name
        type(barostat_params_t), intent(in) :: p
        class(barostat_t), allocatable, intent(out) :: bs
        select case (trim(name))
        case ('c_rescale')
            allocate (c_rescale_t :: bs)
        case ('mc')
            allocate (mc_barostat_t :: bs)
        case ('mttk')
            allocate (mttk_t :: bs)
        case default
            allocate (barostat_none_t :: bs)
        end select
        call bs%init(p)
    end subroutine new_barostat

end module terrace_barostat_factory
