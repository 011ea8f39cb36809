!> CSV output of terrace-analyze: one header line naming every column with its unit, then one
!> row per point (rank 0 writes; collective, so that a file that cannot be written stops every rank).
module terrace_analysis_csv
    use terrace_kinds, only: dp
    use terrace_mpi_env, only: world
    use terrace_errors, only: check_all
    implicit none
    private
    public :: write_csv, unit_label

contains

    !> cols(point, column); header is the comma-separated list of column names with units.
    subroutine write_csv(path, header, cols, comment)
        character(len=*), intent(in) :: path, header
        real(dp), intent(in) :: cols(:, :)
        character(len=*), intent(in), optional :: comment
        integer :: unit, ios, i
        character(len=32) :: fmt
        ios = 0
        if (world%rank == 0) then
            open (newunit=unit, file=path, status='replace', action='write', iostat=ios)
            if (ios == 0) then
                if (present(comment)) write (unit, '(a)') '# '//trim(comment)
                write (unit, '(a)') trim(header)
                write (fmt, '(a,i0,a)') '(', size(cols, 2), '(es24.16e3,:,","))'
                do i = 1, size(cols, 1)
                    write (unit, fmt) cols(i, :)
                end do
                close (unit)
            end if
        end if
        call check_all(ios == 0, path//': cannot write the output file (&analysis output_prefix)')
    end subroutine write_csv

    !> "(unit)" or "(reduced)" when the file gives no unit.
    function unit_label(u) result(s)
        character(len=*), intent(in) :: u
        character(len=:), allocatable :: s
        if (len_trim(u) == 0) then
            s = '(reduced)'
        else
            s = '('//trim(u)//')'
        end if
    end function unit_label

end module terrace_analysis_csv
