!> Data files as LAMMPS write_data writes them by default carry the force field: 'Pair Coeffs'
!> (i epsilon sigma) or 'PairIJ Coeffs' (i j epsilon sigma [cutoff]). The deck's &potential stays
!> the one source of the force field; the file's coefficients are compared with it:
!>   epsilon(i,j), sigma(i,j) of the deck, geometric mixing where a pair is not given
!>   (eps_ij = sqrt(eps_ii eps_jj), sigma_ij = sqrt(sigma_ii sigma_jj), as LAMMPS mixes lj/cut),
!> equal to the file's to a relative 1e-5 (write_data prints 6 significant digits): a note when
!> they agree, an error naming both values when they do not, or when the file's pair style is
!> not one of the deck's LJ styles. Coefficient sections that do not apply (Bond Coeffs, ...) were
!> skipped by the reader; they are listed in the same note.
module terrace_data_coeffs
    use terrace_kinds, only: dp
    use terrace_config, only: config_t, is_unset
    use terrace_atom_table, only: atom_table_t
    use terrace_lammps_data, only: read_lammps_data
    use, intrinsic :: iso_fortran_env, only: output_unit
    implicit none
    private

    public :: read_data_checked

contains

    !> Read the data file of &system read_data (rank 0) and check its coefficients against the
    !> deck. Errors are returned in t%ok / t%error as the reader's are.
    subroutine read_data_checked(cfg, t)
        type(config_t), intent(in) :: cfg
        type(atom_table_t), intent(out) :: t
        integer :: i, j
        real(dp) :: deck(2), file(2)
        character(len=96) :: s
        logical :: lj_style
        call read_lammps_data(trim(cfg%read_data), t)
        if (.not. t%ok) return
        if (len_trim(t%notes) > 0) write (output_unit, '(a)') 'read_data: skipped the sections'//trim(t%notes)// &
            ' of '//trim(cfg%read_data)//' (they do not apply to an atomic system)'
        if (.not. any(t%coeff_given)) return
        lj_style = len_trim(cfg%pot_style%data_coeffs) > 0     ! the style reads LAMMPS pair coefficients
        if (.not. lj_style) then
            t%ok = .false.
            t%error = trim(cfg%read_data)//': &system: read_data: the file holds pair coefficients ('// &
                      trim(t%coeff_style)//') but &potential style is '''//trim(cfg%potential)// &
                      ''' (remove the Pair Coeffs section, or use an LJ style with the same coefficients)'
            return
        end if
        if (len_trim(t%coeff_style) > 0 .and. index(t%coeff_style, trim(cfg%pot_style%data_coeffs)) /= 1) then
            t%ok = .false.
            t%error = trim(cfg%read_data)//': &system: read_data: the pair coefficients are for pair style '''// &
                      trim(t%coeff_style)//''', not an LJ style like &potential style = '''//trim(cfg%potential)//''''
            return
        end if
        do j = 1, t%ntypes
            do i = 1, t%ntypes
                if (.not. t%coeff_given(i, j)) cycle
                deck = [pick(cfg%epsilon, i, j), pick(cfg%sigma, i, j)]
                file = t%coeff(:, i, j)
                if (any(deck < 0)) cycle                  ! type not in the deck: engine reports it
                if (any(abs(deck - file) > 1.0e-5_dp*max(abs(deck), abs(file), tiny(1.0_dp)))) then
                    write (s, '(2(a,i0),2(a,es12.5),a)') 'pair ', i, ' ', j, ': epsilon ', file(1), ', sigma ', &
                        file(2), ' in the file'
                    t%ok = .false.
                    t%error = trim(cfg%read_data)//': &system: read_data: its pair coefficients disagree with '// &
                              '&potential epsilon, sigma ('//trim(s)//'; '//trim(num2(deck))//' in the deck); '// &
                              'the deck defines the force field: make them agree or remove the section'
                    return
                end if
            end do
        end do
        write (output_unit, '(a)') 'read_data: the pair coefficients in '//trim(cfg%read_data)// &
            ' agree with &potential (the deck defines the force field)'
    contains
        function num2(v) result(txt)
            real(dp), intent(in) :: v(2)
            character(len=64) :: txt
            write (txt, '(a,es12.5,a,es12.5)') 'epsilon ', v(1), ', sigma ', v(2)
        end function num2
    end subroutine read_data_checked

    !> The deck's value for pair (i, j): given, or mixed geometrically; -1 when type i or j has none.
    real(dp) function pick(a, i, j)
        real(dp), intent(in) :: a(:, :)
        integer, intent(in) :: i, j
        pick = -1
        if (i > size(a, 1) .or. j > size(a, 1)) return
        if (.not. is_unset(a(i, j))) then
            pick = a(i, j)
        else if (.not. is_unset(a(j, i))) then
            pick = a(j, i)
        else if (.not. (is_unset(a(i, i)) .or. is_unset(a(j, j)))) then
            pick = sqrt(a(i, i)*a(j, j))
        end if
    end function pick

end module terrace_data_coeffs
