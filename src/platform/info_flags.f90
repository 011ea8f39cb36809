!> The command-line flags every Terrace program answers the same way: --help and --version.
module terrace_info_flags
    use terrace_mpi_env, only: world, end_mpi
    use terrace_version, only: terrace_version_string
    use, intrinsic :: iso_fortran_env, only: output_unit
    implicit none
    private
    public :: answer_info_flag

    abstract interface
        subroutine printer()
        end subroutine printer
    end interface

contains

    !> --help / -h prints the program's help, --version / -V its version (rank 0), and the program
    !> ends with status 0; any other argument is left to the caller.
    subroutine answer_info_flag(arg, program_name, print_help)
        character(len=*), intent(in) :: arg, program_name
        procedure(printer) :: print_help
        select case (trim(arg))
        case ('--help', '-h')
            if (world%rank == 0) call print_help()
        case ('--version', '-V')
            if (world%rank == 0) write (output_unit, '(a)') program_name//' '//terrace_version_string
        case default
            return
        end select
        call end_mpi()
        stop
    end subroutine answer_info_flag

end module terrace_info_flags
