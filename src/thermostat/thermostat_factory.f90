!> The one place that maps a &thermostat style name to its type. Adding a thermostat: a new file
!> with a type extending thermostat_t, its name in `names` and one case in new_thermostat.
module terrace_thermostat_factory
    use terrace_thermostat, only: thermostat_t, thermostat_params_t, thermostat_none_t
    use terrace_thermostat_langevin, only: langevin_t
    use terrace_thermostat_csvr, only: csvr_t
    use terrace_thermostat_nose_hoover, only: nose_hoover_t
    use terrace_thermostat_andersen, only: andersen_t
    implicit none
    private

    character(len=12), parameter :: names(5) = [character(len=12) :: 'none', 'langevin', 'csvr', 'nose_hoover', &
                                                                      'andersen']

    public :: is_thermostat_style, new_thermostat, thermostat_styles, thermostat_styles_for_events, &
              thermostat_styles_with_chain, thermostat_styles_colliding, thermostat_names_with_chain

contains

    pure logical function is_thermostat_style(name)
        character(len=*), intent(in) :: name
        is_thermostat_style = any(names == name)
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

    !> Every style name, quoted: "'none', 'langevin', ..." (for messages).
    function thermostat_styles() result(list)
        character(len=:), allocatable :: list
        integer :: k
        list = ''
        do k = 1, size(names)
            list = list//merge(', ', '  ', k > 1)//"'"//trim(names(k))//"'"
        end do
        list = adjustl(list)
    end function thermostat_styles

    !> The styles energy stepping can run, each with how it acts, and 'none' (for messages).
    function thermostat_styles_for_events() result(list)
        character(len=:), allocatable :: list
        list = styles_that('events')//"or 'none'"
    end function thermostat_styles_for_events

    !> The styles that take &thermostat chain_length (for messages).
    function thermostat_styles_with_chain() result(list)
        character(len=:), allocatable :: list
        list = styles_that('chain')
    end function thermostat_styles_with_chain

    !> The styles whose atoms collide one by one at exact times, each with how it acts (event-driven
    !> runs; for messages): "'name', how it acts; ".
    function thermostat_styles_colliding() result(list)
        character(len=:), allocatable :: list
        list = styles_that('collisions')
    end function thermostat_styles_colliding

    !> The names of the styles that take chain_length, quoted and joined by ' or ' (for messages).
    function thermostat_names_with_chain() result(list)
        character(len=:), allocatable :: list
        list = styles_that('chain names')
    end function thermostat_names_with_chain

    !> The active styles whose prototype answers yes: 'events' (runs with energy stepping: "'name',
    !> how it acts; " each) or 'chain' (takes chain_length: "style = 'name'", joined by ' or ').
    function styles_that(what) result(list)
        character(len=*), intent(in) :: what
        character(len=:), allocatable :: list
        class(thermostat_t), allocatable :: ts
        integer :: k
        list = ''
        do k = 1, size(names)
            call new_thermostat(names(k), thermostat_params_t(), ts)
            if (.not. ts%active()) cycle
            if (what == 'events' .and. len_trim(ts%traits%event_note) > 0) then
                list = list//"'"//trim(names(k))//"', "//trim(ts%traits%event_note)//'; '
            else if (what == 'collisions' .and. ts%traits%collides_atoms) then
                list = list//"'"//trim(names(k))//"', "//trim(ts%traits%event_note)//'; '
            else if (what == 'chain' .and. ts%traits%takes_chain) then
                if (len(list) > 0) list = list//' or '
                list = list//"style = '"//trim(names(k))//"'"
            else if (what == 'chain names' .and. ts%traits%takes_chain) then
                if (len(list) > 0) list = list//' or '
                list = list//"'"//trim(names(k))//"'"
            end if
        end do
    end function styles_that

end module terrace_thermostat_factory
