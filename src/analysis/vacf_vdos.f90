!> Velocity autocorrelation and vibrational density of states.
!>
!>     C(tau) = sum_i m_i < v_i(t) . v_i(t + tau) >_t            (mass-weighted; average over origins)
!>     g(nu)  = 2 D N * int_{-T}^{T} [C(tau)/C(0)] w(tau) exp(-2 pi i nu tau) dtau / 2
!>            = 2 D N dt [ c(0) + 2 sum_{j=1}^{M} c(j) w(j) cos(2 pi nu j dt) ],   c = C/C(0)
!>
!> C is computed exactly by FFT (fft_correlation: zero padding to >= 2 n, no wrap-around) for
!> lags 0..M (M = correlation_time / dt), divided by the number of origins n - tau. w is a window
!> that goes to zero at lag M (Hann by default; 'blackman'; 'none'), which sets the resolution
!> (about 2 / (M dt) for Hann, the full width of a line). The windowed correlation is zero-padded to
!> zero_padding * 2 M points (a power of two) before its transform, which only interpolates the
!> spectrum. The normalisation makes the discrete spectrum integrate (trapezoid rule from 0 to the
!> Nyquist frequency 1/(2 dt)) to the number of degrees of freedom D N exactly:
!>     int_0^{nu_Nyquist} g(nu) dnu = D N.
!> Frequencies are cycles per time unit (THz for ps); g is in time units (states per THz).
!> Parallel over atoms: each rank reads the velocities of its block of atoms for all selected
!> frames and sums their power spectra; one reduction.
module terrace_vacf_vdos
    use terrace_kinds, only: dp, i8, pi
    use terrace_text, only: fixed
    use terrace_mpi_env, only: world
    use terrace_errors, only: check_all, warn
    use terrace_analysis_config, only: analysis_config_t, is_unset, frame_window, frame_plan_t
    use terrace_h5md_reader, only: h5md_trajectory_t, el_velocity
    use terrace_id_blocks, only: id_block
    use terrace_fft_correlation, only: autocorrelation_t, cosine_spectrum, next_power_of_two
    use terrace_analysis_csv, only: write_csv, unit_label
    use, intrinsic :: iso_fortran_env, only: output_unit
    implicit none
    private

    type, public, extends(frame_plan_t) :: vdos_plan_t
        real(dp) :: dt = 0
        integer :: maxlag = 0
        integer :: length = 0
    end type vdos_plan_t

    public :: plan_vdos, run_vdos


contains

    !> Check the selection against the file (frames, times, correlation length) before anything runs.
    subroutine plan_vdos(traj, cfg, plan)
        type(h5md_trajectory_t), intent(in) :: traj
        type(analysis_config_t), intent(in) :: cfg
        type(vdos_plan_t), intent(out) :: plan
        character(len=1024) :: a
        call frame_window(cfg, traj%frames(el_velocity), traj%where('velocity/value'), 1_i8, plan)
        plan%dt = traj%time_step(el_velocity, plan%f0, plan%nsel, plan%stride, 'the VACF/VDOS')
        if (is_unset(cfg%correlation_time)) then
            plan%maxlag = int(plan%nsel/2)
        else
            plan%maxlag = nint(cfg%correlation_time/plan%dt)
            call check_all(plan%maxlag >= 1, cfg%where('correlation_time')//': shorter than the time between '// &
                           'the selected frames of '//traj%path)
        end if
        write (a, '(i0,a,i0,a)') 2*plan%maxlag, ' frames; the selection of '//traj%path//' has ', plan%nsel, ' frames'
        call check_all(plan%maxlag >= 1 .and. plan%nsel >= 2*int(plan%maxlag, i8), &
                       cfg%where('correlation_time')//': too few frames for this correlation length (the VACF up '// &
                       'to lag M frames needs at least 2 M frames: '//trim(a)//'; lower correlation_time or '// &
                       'select more frames)')
        plan%length = next_power_of_two(max(cfg%zero_padding*2*plan%maxlag, 2*plan%maxlag + 2))
    end subroutine plan_vdos

    subroutine run_vdos(traj, cfg, plan)
        type(h5md_trajectory_t), intent(in) :: traj
        type(analysis_config_t), intent(in) :: cfg
        type(vdos_plan_t), intent(in) :: plan
        type(autocorrelation_t) :: ac
        real(dp), allocatable :: v(:, :, :), series(:), c(:), f(:), s(:), cols(:, :)
        integer(i8) :: a0, na, i
        integer :: k, j, M, D, L, ipeak
        real(dp) :: dof, c0, integral, x
        character(len=:), allocatable :: tl, fl

        M = plan%maxlag; D = traj%dimension; L = plan%length
        call id_block(traj%natoms, world%nprocs, world%rank, a0, na)
        a0 = a0 - 1          ! 0-based start of this rank's block
        allocate (v(D, max(na, 1_i8), plan%nsel), series(plan%nsel), c(0:M), f(0:M), s(0:L/2))
        call traj%read_real(el_velocity, plan%f0, plan%nsel, plan%stride, a0, na, v)
        call ac%setup(int(plan%nsel))
        do i = 1, na
            do k = 1, D
                series = v(k, i, :)
                call ac%add(series, traj%mass(a0 + i))
            end do
        end do
        deallocate (v)
        call ac%reduce()
        call ac%correlation(M, c)
        call ac%destroy()
        do j = 0, M
            c(j) = c(j)/real(plan%nsel - j, dp)
        end do
        call check_all(c(0) > 0, traj%where('velocity/value')//': every selected velocity is zero (no VDOS)')
        c0 = c(0)
        c = c/c0
        do j = 0, M
            x = pi*real(j, dp)/real(M, dp)
            select case (trim(cfg%window))
            case ('hann'); f(j) = c(j)*0.5_dp*(1 + cos(x))
            case ('blackman'); f(j) = c(j)*(0.42_dp + 0.5_dp*cos(x) + 0.08_dp*cos(2*x))
            case default; f(j) = c(j)
            end select
        end do
        call cosine_spectrum(f, M, L, s)
        dof = real(D, dp)*real(traj%natoms, dp)
        s = 2*dof*plan%dt*s
        integral = (sum(s) - 0.5_dp*(s(0) + s(L/2)))/(L*plan%dt)
        ipeak = maxloc(s(1:), 1)

        tl = unit_label(traj%unit_time)
        fl = '(1/'//trim(traj%unit_time)//')'
        if (trim(traj%unit_time) == 'ps') fl = '(THz)'
        if (len_trim(traj%unit_time) == 0) fl = '(reduced)'
        allocate (cols(M + 1, 3))
        do j = 0, M
            cols(j + 1, :) = [j*plan%dt, c(j), c(j)*c0/dof]
        end do
        call write_csv(trim(cfg%output_prefix)//'_vacf.csv', 'time '//tl//',vacf_normalised (1),'// &
                       'vacf_mass_weighted_per_dof (mass*velocity^2 in file units)', cols)
        deallocate (cols)
        allocate (cols(L/2 + 1, 2))
        do j = 0, L/2
            cols(j + 1, :) = [j/(L*plan%dt), s(j)]
        end do
        call write_csv(trim(cfg%output_prefix)//'_vdos.csv', 'frequency '//fl//',vdos '//tl// &
                       ' (integrates to D N over frequency)', cols)
        if (world%rank == 0) then
            write (output_unit, '(a)') 'VDOS (velocity autocorrelation, FFTW):'
            write (output_unit, '(a,i0,a,es12.5,a,i0,a,es12.5,a)') '  frames: ', plan%nsel, ' at dt = ', plan%dt, &
                ' ; correlation up to ', M, ' lags (', M*plan%dt, ')'
            write (output_unit, '(a,a,a,es12.5,a,es12.5,a,i0)') '  window: ', trim(cfg%window), &
                ' ; resolution 1/(M dt) = ', 1/(M*plan%dt), ' ; grid ', 1/(L*plan%dt), ' ; transform length ', L
            write (output_unit, '(a,es22.15)') '  degrees of freedom D N = '//fixed(dof, 1)// &
                ' ; integral of the VDOS = ', integral
            write (output_unit, '(a,es14.7,1x,a)') '  highest peak at ', ipeak/(L*plan%dt), fl
            write (output_unit, '(a)') '  wrote '//trim(cfg%output_prefix)//'_vacf.csv, '//trim(cfg%output_prefix)// &
                '_vdos.csv'
        end if
        ! what the sampling cannot resolve: a peak below the resolution 1/(M dt), or a
        ! spectrum still high at the Nyquist frequency 1/(2 dt) (frames too far apart: aliased)
        if (ipeak/(L*plan%dt) < 1/(M*plan%dt)) call warn('VDOS: the highest peak ('// &
            fixed(ipeak/(L*plan%dt), 6)//' '//trim(fl)//') lies below the resolution 1/(M dt) = '// &
            fixed(1/(M*plan%dt), 6)//' '//trim(fl)//': use a longer run and correlation_time; the peak is not resolved')
        if (sum(s(L/2 - L/20:L/2)) > 0.05_dp*sum(s(0:L/2))) call warn('VDOS: more than 5 % of the spectrum '// &
            'lies in the top tenth below the Nyquist frequency 1/(2 dt) = '//fixed(1/(2*plan%dt), 4)//' '// &
            trim(fl)//': the frames are too far apart for the vibrations (aliased); write frames more often')
    end subroutine run_vdos

end module terrace_vacf_vdos
