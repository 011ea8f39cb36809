!> terrace-analyze: observables from H5MD trajectories (VACF/VDOS, g(r), MSD and diffusion, S(q)).
!>   terrace-analyze ANALYSIS.nml [--KEY=VALUE ...]
!>   terrace-analyze --trajectory_file=run.h5 --compute=vdos,rdf [--KEY=VALUE ...]
!>   terrace-analyze --version | --help
!> Everything is checked (keys, the file's datasets and shapes, frame counts against the requested
!> correlation lengths) before any analysis runs, so bad input writes no output file.
program terrace_analyze
    use terrace_kinds, only: dp
    use terrace_text, only: fixed
    use terrace_mpi_env, only: world, start_mpi, end_mpi
    use terrace_errors, only: stop_all
    use terrace_files, only: peak_memory_kib
    use terrace_version, only: terrace_version_string
    use terrace_info_flags, only: answer_info_flag
    use terrace_analysis_config, only: analysis_config_t, read_analysis_config
    use terrace_h5md_reader, only: h5md_trajectory_t, el_position, el_velocity
    use terrace_vacf_vdos, only: vdos_plan_t, plan_vdos, run_vdos
    use terrace_rdf, only: rdf_plan_t, plan_rdf, run_rdf
    use terrace_msd_diffusion, only: msd_plan_t, plan_msd, run_msd
    use terrace_structure_factor, only: sq_plan_t, plan_sq, run_sq
    use mpi_f08, only: MPI_Wtime
    use, intrinsic :: iso_fortran_env, only: output_unit
    implicit none

    type(analysis_config_t) :: cfg
    type(h5md_trajectory_t) :: traj
    type(vdos_plan_t) :: vdos
    type(rdf_plan_t) :: rdf
    type(msd_plan_t) :: msd
    type(sq_plan_t) :: sq
    character(len=4096) :: arg
    character(len=4096), allocatable :: flags(:)
    character(len=:), allocatable :: path
    integer :: k, nflags
    real(dp) :: t0

    call start_mpi()
    t0 = MPI_Wtime()
    path = ''
    allocate (flags(command_argument_count()))
    nflags = 0
    k = 1
    do while (k <= command_argument_count())
        call get_command_argument(k, arg)
        call answer_info_flag(arg, 'terrace-analyze', print_help)
        if (arg(1:2) == '--') then
            nflags = nflags + 1; flags(nflags) = arg
            if (index(arg, '=') == 0 .and. k < command_argument_count()) then
                k = k + 1
                call get_command_argument(k, arg)
                nflags = nflags + 1; flags(nflags) = arg
                flags(nflags - 1) = trim(flags(nflags - 1))//'='//trim(arg)
                nflags = nflags - 1
            end if
        else if (arg(1:1) == '-') then
            call stop_all("unknown option '"//trim(arg)//"' (see terrace-analyze --help)", 2)
        else
            if (len(path) > 0) call stop_all('give one namelist file (see terrace-analyze --help)', 2)
            path = trim(arg)
        end if
        k = k + 1
    end do
    if (len(path) == 0 .and. nflags == 0) &
        call stop_all('no input (usage: terrace-analyze ANALYSIS.nml | --trajectory_file=F --compute=LIST; see '// &
                      'terrace-analyze --help)', 2)

    call read_analysis_config(path, flags(1:nflags), cfg)
    call traj%open(cfg%trajectory_file, cfg%particles_group, cfg%rdf .or. cfg%msd .or. cfg%sq, cfg%vdos, &
                   'g(r), MSD and S(q) need positions', &
                   "the VDOS needs velocities: write them with &output trajectory_fields = 'position velocity'")
    ! plan everything first: all checks pass before any output is written
    if (cfg%vdos) call plan_vdos(traj, cfg, vdos)
    if (cfg%rdf) call plan_rdf(traj, cfg, rdf)
    if (cfg%msd) call plan_msd(traj, cfg, msd)
    if (cfg%sq) call plan_sq(traj, cfg, sq)
    ! every value the analyses will read is finite and in range (one error line, no output yet)
    if (cfg%vdos) call traj%check_values(el_velocity, vdos%f0, vdos%nsel, vdos%stride)
    if (cfg%rdf) call traj%check_values(el_position, rdf%f0, rdf%nsel, rdf%stride)
    if (cfg%msd) call traj%check_values(el_position, msd%f0, msd%nsel, msd%stride)
    if (cfg%sq) call traj%check_values(el_position, sq%f0, sq%nsel, sq%stride)
    if (world%rank == 0) then
        write (output_unit, '(a)') 'terrace-analyze '//terrace_version_string//': '//trim(cfg%trajectory_file)
        write (output_unit, '(a,i0,a,i0,a,i0,a)') '  ', traj%natoms, ' atoms, dimension ', traj%dimension, ', ', &
            world%nprocs, ' rank(s)'
    end if

    if (cfg%vdos) call run_vdos(traj, cfg, vdos)
    if (cfg%rdf) call run_rdf(traj, cfg, rdf)
    if (cfg%msd) call run_msd(traj, cfg, msd)
    if (cfg%sq) call run_sq(traj, cfg, sq)
    call traj%close()
    if (world%rank == 0) write (output_unit, '(a,i0,a)') 'Analysis time: '//fixed(MPI_Wtime() - t0, 3)//' s; peak memory ', &
        peak_memory_kib(), ' KiB (rank 0)'
    call end_mpi()

contains

    subroutine print_help()
        write (output_unit, '(a)') 'usage: terrace-analyze ANALYSIS.nml [--KEY=VALUE ...]', &
            '       terrace-analyze --trajectory_file=run.h5 --compute=vdos,rdf,msd,sq [--KEY=VALUE ...]', &
            '       mpirun -np N terrace-analyze ...', &
            '', &
            'Reads an H5MD trajectory and writes CSV curves <output_prefix>_{vacf,vdos,rdf,msd,diffusion,sq}.csv.', &
            'Keys of &analysis (flags --KEY=VALUE override the file):', &
            '  trajectory_file   H5MD file (required)            particles_group  (all)', &
            '  compute           list of vdos, rdf, msd, sq      output_prefix    (analysis)', &
            '  first_frame (1), last_frame (-1 = last), frame_stride (1)', &
            '  vdos: correlation_time (half the span), window (hann | blackman | none), zero_padding (4)', &
            '  rdf:  rdf_r_max (half the shortest edge), rdf_bins (200), rdf_every (1)', &
            '  msd:  msd_max_time (half a block), msd_fit_start, msd_fit_end, msd_blocks (5)', &
            '  sq:   sq_q_max (3 * 2 pi / mean spacing), sq_bin_width (2 pi / longest edge), sq_every (1)', &
            'Details: doc/analysis.md'
    end subroutine print_help

end program terrace_analyze
