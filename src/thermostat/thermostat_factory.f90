!> The one place that maps a &thermostat style name to its type. Adding a thermostat: a new file
!> with a type extending thermostat_t, and one line in each list below.
module terrace_thermostat_factory
    use terrace_thermostat, only: thermostat_t, thermostat_params_t, thermostat_none_t
    use terrace_thermostat_langevin, only: langevin_t
    use terrace_thermostat_csvr, only: csvr_t
    use terrace_thermostat_nose_hoover, only: nose_hoover_t
    use terrace_thermostat_andersen, only: andersen_t
    implicit none
    private

    !> The style names, for messages ("allowed: ...").
    character(len=*), parameter, public :: thermostat_style_list = &
        "'none', 'langevin', 'csvr', 'nose_hoover', 'andersen'"

    public :: is_thermostat_style, new_thermostat

contains

    pure logical function is_thermostat_style(name)
        character(len=*), intent(in) :: name
        is_thermostat_style = index(thermostat_style_list, "'"//trim(name)//"'") > 0 .and. len_trim(name) > 0
    end function is_thermostat_style

    !> A thermostat of the named style, set up from p ('none' and unknown names: no thermostat).
    subroutine new_thermostat(name, p, ts)
        character(len=*), intent(in) :: name
        type(thermostat_params_t), intent(in) :: p
        class(thermostat_t), allocatable, intent(out) :: ts
        select case (trim(name))
        case ('langevin')
            allocate (langevin_t :: ts)
        case ('csvr')
            allocate (csvr_t :: ts)
        case ('nose_hoover')
            allocate (nose_hoover_t :: ts)
        case ('andersen')
            allocate (andersen_t :: ts)
        case default
            allocate (thermostat_none_t :: ts)
        end select
        call ts%init(p)
    end subroutine new_thermostat

end module terrace_thermostat_factory
