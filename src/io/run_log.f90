!> End-of-run log: loop time, atom-steps per second, the per-phase timing table (average and
!> maximum over ranks, share of the loop), neighbour-list builds, the list's pairs per rank (the
!> work of the pair passes: its spread over the ranks is their load balance), and peak memory per atom.
module terrace_run_log
    use terrace_kinds, only: dp, i8
    use terrace_text, only: fixed
    use terrace_timers, only: timers_t, n_timers, timer_names
    use terrace_mpi_env, only: world
    use terrace_files, only: peak_memory_kib
    use terrace_run_summary, only: summary_put
    use mpi_f08, only: MPI_Reduce, MPI_DOUBLE_PRECISION, MPI_INTEGER8, MPI_SUM, MPI_MAX, MPI_MIN
    use, intrinsic :: iso_fortran_env, only: output_unit
    implicit none
    private

    public :: print_run_log, peak_memory_kib

contains

    subroutine print_run_log(timers, loop_time, natoms, steps, builds, label, list_note, pairs, pairs_what)
        type(timers_t), intent(in) :: timers
        real(dp), intent(in) :: loop_time
        integer(i8), intent(in) :: natoms, steps
        integer, intent(in) :: builds
        character(len=*), intent(in) :: label
        character(len=*), intent(in), optional :: list_note   !< lines after the build count (a schedule)
        integer(i8), intent(in), optional :: pairs            !< this rank's list length (0: no list)
        character(len=*), intent(in), optional :: pairs_what  !< what pairs counts (absent or '': the atom list's pairs)
        character(len=:), allocatable :: what
        real(dp) :: phase(n_timers), avg(n_timers), mx(n_timers), mem, memsum, other
        integer(i8) :: p(1), psum(1), pmin(1), pmax(1)
        integer :: k
        phase = timers%seconds()
        call MPI_Reduce(phase, avg, n_timers, MPI_DOUBLE_PRECISION, MPI_SUM, 0, world%comm)
        call MPI_Reduce(phase, mx, n_timers, MPI_DOUBLE_PRECISION, MPI_MAX, 0, world%comm)
        mem = real(peak_memory_kib(), dp)
        call MPI_Reduce(mem, memsum, 1, MPI_DOUBLE_PRECISION, MPI_SUM, 0, world%comm)
        p = 0
        if (present(pairs)) p = pairs
        call MPI_Reduce(p, psum, 1, MPI_INTEGER8, MPI_SUM, 0, world%comm)
        call MPI_Reduce(p, pmin, 1, MPI_INTEGER8, MPI_MIN, 0, world%comm)
        call MPI_Reduce(p, pmax, 1, MPI_INTEGER8, MPI_MAX, 0, world%comm)
        if (world%rank /= 0) return
        what = 'List pairs (within rc + skin, last build)'
        if (present(pairs_what)) then
            if (len(pairs_what) > 0) what = pairs_what
        end if
        avg = avg/world%nprocs
        write (output_unit, '(a,a,a,i0,a,i0,a,i0,a)') 'Loop time: ', fixed(loop_time, 4), ' s on ', world%nprocs, &
            ' rank(s) for ', steps, ' '//label//' with ', natoms, ' atoms'
        if (loop_time > 0) write (output_unit, '(a,es12.5)') 'Performance: atom-steps/s = ', &
            real(natoms, dp)*real(steps, dp)/loop_time
        write (output_unit, '(a)') 'Phase      avg time (s)   max time (s)   %loop'
        ! 'Other' is what the measured phases leave of the loop (integration, bookkeeping)
        other = loop_time - sum(avg(1:n_timers - 1))
        avg(n_timers) = other; mx(n_timers) = other
        do k = 1, n_timers
            write (output_unit, '(a8,2x,f13.4,2x,f13.4,2x,f6.1)') timer_names(k), avg(k), mx(k), &
                100*avg(k)/max(loop_time, tiny(1.0_dp))
        end do
        call put_summary()
        write (output_unit, '(a,i0)') 'Neighbour list builds: ', builds
        if (present(list_note)) then
            if (len(list_note) > 0) write (output_unit, '(a)') list_note
        end if
        if (psum(1) > 0) then
            if (world%nprocs > 1) then
                write (output_unit, '(a,i0,a,i0,a,i0,a,a)') what//': ', psum(1), &
                    ' in all ranks; per rank min ', pmin(1), ', max ', pmax(1), ', max/average ', &
                    fixed(real(pmax(1), dp)*world%nprocs/real(psum(1), dp), 3)
            else
                write (output_unit, '(a,i0)') what//': ', psum(1)
            end if
        end if
        ! per atom only where the atoms dominate the memory (a 7-atom cluster measures the libraries)
        if (natoms >= 10000) then
            write (output_unit, '(a)') 'Peak memory: '//fixed(memsum/1024, 1)//' MiB in all ranks, '// &
                fixed(1024*memsum/real(natoms, dp), 1)//' bytes/atom'
        else
            write (output_unit, '(a)') 'Peak memory: '//fixed(memsum/1024, 1)//' MiB in all ranks (mostly the '// &
                'libraries: too few atoms for a per-atom figure)'
        end if
    contains

        !> The same figures in the run summary.
        subroutine put_summary()
            call summary_put('timing/loop_time_s', loop_time)
            call summary_put('timing/'//label, steps)
            call summary_put('timing/atoms', natoms)
            if (loop_time > 0) call summary_put('timing/atom_steps_per_s', real(natoms, dp)*real(steps, dp)/loop_time)
            do k = 1, n_timers
                call summary_put('timing/phases/'//trim(adjustl(timer_names(k)))//'/avg_s', avg(k))
                call summary_put('timing/phases/'//trim(adjustl(timer_names(k)))//'/max_s', mx(k))
                call summary_put('timing/phases/'//trim(adjustl(timer_names(k)))//'/percent_loop', &
                                 100*avg(k)/max(loop_time, tiny(1.0_dp)))
            end do
            call summary_put('neighbor/builds', builds)
            if (psum(1) > 0) then
                call summary_put('neighbor/list_pairs', psum(1))
                call summary_put('neighbor/list_pairs_min_rank', pmin(1))
                call summary_put('neighbor/list_pairs_max_rank', pmax(1))
            end if
            call summary_put('memory/peak_mib_all_ranks', memsum/1024)
            if (natoms >= 10000) call summary_put('memory/bytes_per_atom', 1024*memsum/real(natoms, dp))
        end subroutine put_summary

    end subroutine print_run_log

end module terrace_run_log
