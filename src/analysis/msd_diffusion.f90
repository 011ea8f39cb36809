!> Mean-squared displacement and the self-diffusion coefficient.
!>
!>     MSD(tau) = < |u_i(t + tau) - u_i(t)|^2 >_{i, t},     D = slope / (2 d)   (Einstein relation)
!>
!> u are unwrapped positions: u = x + image * L (the box edges of each frame) when the file has an
!> image element, else unwrapped by continuity between consecutive selected frames (minimum image
!> of each step; valid while an atom moves less than half a box edge between frames). For every
!> series the average over all origins is exact and costs O(n log n):
!>     sum_t |u(t+m) - u(t)|^2 = A(m) - 2 c(m),   A(m) = sum_{t=0}^{n-1-m} u(t)^2 + u(t+m)^2,
!> with c the autocorrelation by FFT (fft_correlation) and A by a running sum.
!> D comes from a least-squares line through MSD(tau) for tau in [msd_fit_start, msd_fit_end] (default
!> [M/5, M] dt, M = msd_max_time/dt, default a half block). Error bar: the selection is cut into
!> msd_blocks blocks of equal length, D is fitted in each (same window), and the error is the
!> standard error of the block values, s / sqrt(B). Parallel over atoms, one reduction.
module terrace_msd_diffusion
    use terrace_kinds, only: dp, i8
    use terrace_mpi_env, only: world, sum_all
    use terrace_errors, only: check_all, warn
    use, intrinsic :: iso_fortran_env, only: error_unit
    use terrace_analysis_config, only: analysis_config_t, is_unset, frame_window, frame_plan_t
    use terrace_h5md_reader, only: h5md_trajectory_t, el_position, el_image
    use terrace_id_blocks, only: id_block
    use terrace_fft_correlation, only: autocorrelation_t
    use terrace_analysis_csv, only: write_csv, unit_label
    use, intrinsic :: iso_fortran_env, only: output_unit
    implicit none
    private

    type, public, extends(frame_plan_t) :: msd_plan_t
        real(dp) :: dt = 0
        integer :: maxlag = 0, nblocks = 0, block_len = 0, fit_lo = 0, fit_hi = 0
        logical :: use_images = .false., continuity = .false.
    end type msd_plan_t

    public :: plan_msd, run_msd

contains

    subroutine plan_msd(traj, cfg, plan)
        type(h5md_trajectory_t), intent(in) :: traj
        type(analysis_config_t), intent(in) :: cfg
        type(msd_plan_t), intent(out) :: plan
        character(len=160) :: a
        integer :: D
        D = traj%dimension
        call frame_window(cfg, traj%frames(el_position), traj%where('position/value'), 1_i8, plan)
        plan%dt = traj%time_step(el_position, plan%f0, plan%nsel, plan%stride, 'the MSD')
        plan%nblocks = cfg%msd_blocks
        plan%block_len = int(plan%nsel/plan%nblocks)
        if (is_unset(cfg%msd_max_time)) then
            plan%maxlag = plan%block_len/2
        else
            plan%maxlag = nint(cfg%msd_max_time/plan%dt)
        end if
        write (a, '(i0,a,i0,a,i0,a,i0,a)') plan%nblocks, ' blocks of ', plan%block_len, ' frames; lag ', &
            plan%maxlag, ' frames needs blocks of at least ', 2*max(plan%maxlag, 2), ' frames'
        if (is_unset(cfg%msd_max_time)) then      ! (the advice names only keys the user can change)
            call check_all(plan%maxlag >= 2 .and. plan%block_len >= 2*plan%maxlag, cfg%where('msd_blocks')// &
                           ': too few frames in '//traj%path//' for the MSD ('//trim(a)// &
                           '; lower msd_blocks, or select more frames)')
        else
            call check_all(plan%maxlag >= 2 .and. plan%block_len >= 2*plan%maxlag, cfg%where('msd_max_time')// &
                           ': too few frames in '//traj%path//' for this MSD length ('//trim(a)// &
                           '; lower msd_max_time or msd_blocks, or select more frames)')
        end if
        plan%fit_lo = max(1, plan%maxlag/5)
        plan%fit_hi = plan%maxlag
        if (.not. is_unset(cfg%msd_fit_start)) plan%fit_lo = nint(cfg%msd_fit_start/plan%dt)
        if (.not. is_unset(cfg%msd_fit_end)) plan%fit_hi = nint(cfg%msd_fit_end/plan%dt)
        call check_all(plan%fit_hi <= plan%maxlag, cfg%where('msd_fit_end')//': beyond msd_max_time')
        call check_all(plan%fit_hi - plan%fit_lo >= 2, cfg%where('msd_fit_start')//': the fit window holds fewer '// &
                       'than 3 lags (widen msd_fit_start .. msd_fit_end)')
        plan%use_images = traj%has(el_image)
        plan%continuity = any(traj%periodic(1:D)) .and. .not. plan%use_images
    end subroutine plan_msd

    subroutine run_msd(traj, cfg, plan)
        type(h5md_trajectory_t), intent(in) :: traj
        type(analysis_config_t), intent(in) :: cfg
        type(msd_plan_t), intent(in) :: plan
        real(dp), allocatable :: x(:, :, :), msd(:), msd_b(:, :), d_blk(:), err(:)
        integer(i8) :: na
        integer :: b, m, nlag, B_, D
        real(dp) :: d_full, d_mean, d_err

        D = traj%dimension; nlag = plan%maxlag; B_ = plan%nblocks
        call read_unwrapped(traj, plan, na, x)
        allocate (msd(0:nlag), msd_b(0:nlag, B_))
        call msd_curves(traj, plan, na, x, msd, msd_b)
        deallocate (x)
        allocate (d_blk(B_))
        do b = 1, B_
            d_blk(b) = fit_slope(msd_b(:, b), plan%dt, plan%fit_lo, plan%fit_hi)/(2*D)
        end do
        d_full = fit_slope(msd, plan%dt, plan%fit_lo, plan%fit_hi)/(2*D)
        d_mean = sum(d_blk)/B_
        d_err = sqrt(sum((d_blk - d_mean)**2)/(B_ - 1))/sqrt(real(B_, dp))
        allocate (err(0:nlag))
        do m = 0, nlag
            err(m) = sqrt(sum((msd_b(m, :) - sum(msd_b(m, :))/B_)**2)/(B_ - 1))/sqrt(real(B_, dp))
        end do
        call report_msd(traj, cfg, plan, msd, err, [d_full, d_err, d_mean])
    end subroutine run_msd

    !> This rank's block of atoms (na of them), x(D, na, frames): the selected frames' positions,
    !> unwrapped with the images when the file has them, else by continuity across a periodic box.
    subroutine read_unwrapped(traj, plan, na, x)
        type(h5md_trajectory_t), intent(in) :: traj
        type(msd_plan_t), intent(in) :: plan
        integer(i8), intent(out) :: na
        real(dp), allocatable, intent(out) :: x(:, :, :)
        real(dp), allocatable :: edges(:, :)
        integer, allocatable :: img(:, :, :)
        integer(i8) :: a0, i, t
        integer :: n, D
        real(dp) :: L(3), invL(3), step(3)
        D = traj%dimension; n = int(plan%nsel)
        call id_block(traj%natoms, world%nprocs, world%rank, a0, na)
        a0 = a0 - 1          ! 0-based start of this rank's block
        allocate (x(D, max(na, 1_i8), n), edges(3, n))
        call traj%read_real(el_position, plan%f0, plan%nsel, plan%stride, a0, na, x)
        do t = 1, n
            edges(:, t) = traj%box_edges(plan%f0 + 1 + (t - 1)*plan%stride)
        end do
        if (plan%use_images) then
            allocate (img(D, max(na, 1_i8), n))
            call traj%read_int(el_image, plan%f0, plan%nsel, plan%stride, a0, na, img)
            do t = 1, n
                do i = 1, na
                    x(:, i, t) = x(:, i, t) + img(:, i, t)*edges(1:D, t)
                end do
            end do
            deallocate (img)
        else if (plan%continuity) then
            do t = 2, n
                L = 0; invL = 0
                where (traj%periodic)
                    L = edges(:, t); invL = 1/edges(:, t)
                end where
                do i = 1, na
                    step(1:D) = x(:, i, t) - x(:, i, t - 1)
                    step(1:D) = step(1:D) - L(1:D)*anint(step(1:D)*invL(1:D))
                    x(:, i, t) = x(:, i, t - 1) + step(1:D)
                end do
            end do
        end if
    end subroutine read_unwrapped

    !> MSD(m), m = 0..maxlag, over the whole selection (msd) and within each block (msd_b), from
    !> the unwrapped positions x of this rank's na atoms (summed over the ranks).
    subroutine msd_curves(traj, plan, na, x, msd, msd_b)
        type(h5md_trajectory_t), intent(in) :: traj
        type(msd_plan_t), intent(in) :: plan
        integer(i8), intent(in) :: na
        real(dp), intent(in) :: x(:, :, :)
        real(dp), intent(out) :: msd(0:), msd_b(0:, :)
        type(autocorrelation_t) :: full
        type(autocorrelation_t), allocatable :: blk(:)
        real(dp), allocatable :: s(:), sb(:), a_full(:), a_blk(:, :), c(:)
        integer(i8) :: i
        integer :: k, b, m, nlag, B_, n, bl, D
        D = traj%dimension; nlag = plan%maxlag; B_ = plan%nblocks; n = int(plan%nsel); bl = plan%block_len
        call full%setup(n)
        allocate (blk(B_))
        do b = 1, B_
            call blk(b)%setup(bl)
        end do
        allocate (s(n), sb(bl), a_full(0:nlag), a_blk(0:nlag, B_), c(0:nlag))
        a_full = 0; a_blk = 0
        do i = 1, na
            do k = 1, D
                s = x(k, i, :) - sum(x(k, i, :))/n
                call full%add(s, 1.0_dp)
                call add_squares(s, nlag, a_full)
                do b = 1, B_
                    sb = x(k, i, (b - 1)*bl + 1:b*bl)
                    sb = sb - sum(sb)/bl
                    call blk(b)%add(sb, 1.0_dp)
                    call add_squares(sb, nlag, a_blk(:, b))
                end do
            end do
        end do
        call full%reduce(); call sum_all(a_full)
        call full%correlation(nlag, c)
        call full%destroy()
        do m = 0, nlag
            msd(m) = (a_full(m) - 2*c(m))/(real(n - m, dp)*traj%natoms)
        end do
        do b = 1, B_
            call blk(b)%reduce()
            call blk(b)%correlation(nlag, c)
            call blk(b)%destroy()
            call sum_all(a_blk(:, b))
            do m = 0, nlag
                msd_b(m, b) = (a_blk(m, b) - 2*c(m))/(real(bl - m, dp)*traj%natoms)
            end do
        end do
    end subroutine msd_curves

    !> <prefix>_msd.csv (MSD and its block error per lag), <prefix>_diffusion.csv (d: D, its block
    !> error, the blocks' mean; in cm^2/s as well for Angstrom or nm and ps) and the summary.
    subroutine report_msd(traj, cfg, plan, msd, err, d)
        type(h5md_trajectory_t), intent(in) :: traj
        type(analysis_config_t), intent(in) :: cfg
        type(msd_plan_t), intent(in) :: plan
        real(dp), intent(in) :: msd(0:), err(0:), d(3)
        real(dp), allocatable :: cols(:, :)
        real(dp) :: to_cm2s
        character(len=:), allocatable :: ll, tl, dl
        integer :: m
        ll = trim(traj%unit_length); tl = trim(traj%unit_time)
        dl = '('//ll//'^2/'//tl//')'
        if (len(ll) == 0 .or. len(tl) == 0) dl = '(reduced)'
        allocate (cols(plan%maxlag + 1, 3))
        do m = 0, plan%maxlag
            cols(m + 1, :) = [m*plan%dt, msd(m), err(m)]
        end do
        call write_csv(trim(cfg%output_prefix)//'_msd.csv', 'time '//unit_label(tl)//',msd ('//ll//'^2),'// &
                       'msd_block_stderr ('//ll//'^2)', cols)
        deallocate (cols)
        to_cm2s = 0
        if (tl == 'ps') then
            select case (ll)
            case ('Angstrom', 'angstrom', 'Ang', 'A')       ! Terrace writes 'Angstrom' (H5MD/UDUNITS; older files 'Ang')
                to_cm2s = 1.0e-4_dp                           ! 1 A^2/ps = 1e-16 cm^2 / 1e-12 s
            case ('nm')
                to_cm2s = 1.0e-2_dp                           ! 1 nm^2/ps = 1e-14 cm^2 / 1e-12 s
            end select
        end if
        allocate (cols(1, 8))
        cols(1, :) = [d(1), d(2), d(3), plan%fit_lo*plan%dt, plan%fit_hi*plan%dt, real(plan%nblocks, dp), &
                      d(1)*to_cm2s, d(2)*to_cm2s]
        call write_csv(trim(cfg%output_prefix)//'_diffusion.csv', 'D '//dl//',D_stderr_blocks '//dl//',D_block_mean '// &
                       dl//',fit_start '//unit_label(tl)//',fit_end '//unit_label(tl)//',blocks (1),D (cm^2/s),'// &
                       'D_stderr (cm^2/s)', cols)
        if (world%rank == 0) call print_msd_summary(cfg, plan, d, to_cm2s, dl, tl)
    end subroutine report_msd

    !> The summary on standard output (and a warning when D is not meaningful).
    subroutine print_msd_summary(cfg, plan, d, to_cm2s, dl, tl)
        type(analysis_config_t), intent(in) :: cfg
        type(msd_plan_t), intent(in) :: plan
        real(dp), intent(in) :: d(3), to_cm2s
        character(len=*), intent(in) :: dl, tl
        write (output_unit, '(a)') 'MSD and diffusion:'
        write (output_unit, '(a,i0,a,es12.5,a,i0,a,i0,a)') '  frames: ', int(plan%nsel), ' at dt = ', plan%dt, ' ; ', &
            plan%nblocks, ' blocks of ', plan%block_len, ' frames'
        if (plan%use_images) then
            write (output_unit, '(a)') '  unwrapped with image/value'
        else if (plan%continuity) then
            write (output_unit, '(a)') '  no image element: unwrapped by continuity between selected frames'
        end if
        write (output_unit, '(a,es12.5,a,es12.5,a)') '  fit window: ', plan%fit_lo*plan%dt, ' .. ', &
            plan%fit_hi*plan%dt, ' '//unit_label(tl)
        write (output_unit, '(a,es13.6,a,es10.3,1x,a,a,es13.6,a)') '  D = ', d(1), ' +- ', d(2), dl, &
            '  (mean of blocks ', d(3), ')'
        if (to_cm2s > 0) write (output_unit, '(a,es13.6,a,es10.3,a)') '  D = ', d(1)*to_cm2s, ' +- ', &
            d(2)*to_cm2s, ' cm^2/s'
        if (d(1) <= 0 .or. d(2) >= abs(d(1))) write (error_unit, '(a)') 'terrace: warning: MSD: D = '// &
            trim(adjustl(es_text(d(1))))//' +- '//trim(adjustl(es_text(d(2))))//' is not a meaningful '// &
            'diffusion coefficient (negative, or not larger than its block error): the atoms do not diffuse '// &
            'over the fit window (a solid or a cluster), or the run is too short'
        write (output_unit, '(a)') '  wrote '//trim(cfg%output_prefix)//'_msd.csv, '//trim(cfg%output_prefix)// &
            '_diffusion.csv'
    end subroutine print_msd_summary

    !> a(m) += sum_{t=0}^{n-1-m} s(t)^2 + s(t+m)^2 for m = 0..M (s indexed from 1).
    subroutine add_squares(s, M, a)
        real(dp), intent(in) :: s(:)
        integer, intent(in) :: M
        real(dp), intent(inout) :: a(0:M)
        real(dp) :: q
        integer :: k, n
        n = size(s)
        q = 2*sum(s*s)
        a(0) = a(0) + q
        do k = 1, M
            q = q - s(k)**2 - s(n - k + 1)**2
            a(k) = a(k) + q
        end do
    end subroutine add_squares

    function es_text(x) result(t)
        real(dp), intent(in) :: x
        character(len=16) :: t
        write (t, '(es12.4)') x
    end function es_text

    !> Least-squares slope of y(lo..hi) against lag * dt.
    real(dp) function fit_slope(y, dt, lo, hi) result(slope)
        real(dp), intent(in) :: y(0:)
        real(dp), intent(in) :: dt
        integer, intent(in) :: lo, hi
        real(dp) :: tm, ym, sxy, sxx
        integer :: m
        tm = 0; ym = 0
        do m = lo, hi
            tm = tm + m*dt; ym = ym + y(m)
        end do
        tm = tm/(hi - lo + 1); ym = ym/(hi - lo + 1)
        sxy = 0; sxx = 0
        do m = lo, hi
            sxy = sxy + (m*dt - tm)*(y(m) - ym)
            sxx = sxx + (m*dt - tm)**2
        end do
        slope = sxy/sxx
    end function fit_slope

end module terrace_msd_diffusion
