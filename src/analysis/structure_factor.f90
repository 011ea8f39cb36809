!> Static structure factor on the reciprocal lattice of a periodic box, spherically averaged.
!>
!>     S(q) = < |sum_j exp(i q . r_j)|^2 > / N,   q = 2 pi (n1/L1, n2/L2, n3/L3),  0 < |q| <= q_max
!>
!> Every q of one half-space is used (S(-q) = S(q)); the values are averaged in bins of |q| of
!> width sq_bin_width (default 2 pi / L_max, the spacing of the q lattice) and the bin reports the
!> mean |q| of its vectors. The phase factors exp(i 2 pi n x_j / L) are built by repeated
!> multiplication (no transcendental call per q), and the sum over atoms is the contiguous inner
!> loop: O(N * number of q vectors) per frame, exact (no gridding). Defaults: q_max = 3 * 2 pi / a,
!> a = (V/N)^(1/D) the mean spacing. Parallel over frames (a contiguous block per rank, read in
!> batches), one reduction.
module terrace_structure_factor
    use terrace_kinds, only: dp, i8, pi
    use terrace_mpi_env, only: world, sum_all
    use terrace_errors, only: check_all
    use terrace_analysis_config, only: analysis_config_t, is_unset, frame_window, frame_plan_t, batch_values
    use terrace_h5md_reader, only: h5md_trajectory_t, el_position
    use terrace_id_blocks, only: id_block
    use terrace_analysis_csv, only: write_csv, unit_label
    use, intrinsic :: iso_fortran_env, only: output_unit
    implicit none
    private

    type, public, extends(frame_plan_t) :: sq_plan_t
        real(dp) :: q_max = 0, bin_width = 0
        integer :: nbins = 0
    end type sq_plan_t

    public :: plan_sq, run_sq

    integer, parameter :: max_q_index = 4096

contains

    subroutine plan_sq(traj, cfg, plan)
        type(h5md_trajectory_t), intent(in) :: traj
        type(analysis_config_t), intent(in) :: cfg
        type(sq_plan_t), intent(out) :: plan
        real(dp) :: e(3), spacing
        integer :: D
        D = traj%dimension
        call check_all(traj%has_box .and. all(traj%periodic(1:D)), traj%where('box')//': S(q) needs a periodic '// &
                       "box (boundary = 'periodic' in every dimension); drop 'sq' from &analysis compute")
        call frame_window(cfg, traj%frames(el_position), traj%where('position/value'), cfg%sq_every, plan)
        e = traj%box_edges(plan%f0 + 1)
        spacing = (product(e(1:D))/real(traj%natoms, dp))**(1.0_dp/D)
        plan%q_max = 3*2*pi/spacing
        if (.not. is_unset(cfg%sq_q_max)) plan%q_max = cfg%sq_q_max
        plan%bin_width = 2*pi/maxval(e(1:D))
        if (.not. is_unset(cfg%sq_bin_width)) plan%bin_width = cfg%sq_bin_width
        call check_all(plan%q_max*maxval(e(1:D))/(2*pi) < max_q_index, cfg%where('sq_q_max')// &
                       ': too large for this box (more than 4096 reciprocal-lattice steps along an edge)')
        plan%nbins = ceiling(plan%q_max/plan%bin_width) + 1
    end subroutine plan_sq

    subroutine run_sq(traj, cfg, plan)
        type(h5md_trajectory_t), intent(in) :: traj
        type(analysis_config_t), intent(in) :: cfg
        type(sq_plan_t), intent(in) :: plan
        real(dp), allocatable :: x(:, :, :), ssum(:), qsum(:), cnt(:)
        real(dp) :: e(3), frames_done(1)
        integer :: D
        integer(i8) :: fr, natoms, k0, nk, kb, kf, batch, nread

        D = traj%dimension; natoms = traj%natoms
        call id_block(plan%nsel, world%nprocs, world%rank, k0, nk)
        k0 = k0 - 1          ! 0-based start of this rank's block
        batch = max(1_i8, min(nk, batch_values/(D*natoms)))
        allocate (x(D, natoms, batch), ssum(plan%nbins), qsum(plan%nbins), cnt(plan%nbins))
        ssum = 0; qsum = 0; cnt = 0; frames_done = 0
        do kb = 1, nk, batch
            nread = min(batch, nk - kb + 1)
            call traj%read_real(el_position, plan%f0 + (k0 + kb - 1)*plan%stride, nread, plan%stride, 0_i8, natoms, &
                                x(:, :, 1:nread))
            do kf = 1, nread
                fr = plan%f0 + (k0 + kb - 1 + kf - 1)*plan%stride
                e = 1
                e(1:D) = traj%box_edges(fr + 1)
                call add_frame_sq(x(:, :, kf), e, plan, ssum, qsum, cnt)
                frames_done = frames_done + 1
            end do
        end do
        call sum_all(ssum); call sum_all(qsum); call sum_all(cnt); call sum_all(frames_done)
        call report_sq(traj, cfg, plan, ssum, qsum, cnt, frames_done(1))
    end subroutine run_sq

    !> One frame's |rho(q)|^2 / N added to the bins of |q| (ssum; qsum: the sum of |q|; cnt: the
    !> number of q vectors), for every q of one half-space with 0 < |q| <= q_max on the reciprocal
    !> lattice of the box edges e.
    subroutine add_frame_sq(x, e, plan, ssum, qsum, cnt)
        real(dp), intent(in) :: x(:, :), e(3)
        type(sq_plan_t), intent(in) :: plan
        real(dp), intent(inout) :: ssum(:), qsum(:), cnt(:)
        complex(dp), allocatable :: ex(:, :), ey(:, :), ez(:, :), a1(:), a12(:)
        complex(dp) :: rho
        real(dp) :: dq(3), q2, qmax2, q
        integer :: nmax(3), n1, n2, n3, n2lo, n3lo, b, D, k3
        integer(i8) :: natoms, j
        D = size(x, 1); natoms = size(x, 2, kind=i8)
        allocate (a1(natoms), a12(natoms))
        qmax2 = plan%q_max**2
        dq = 2*pi/e
        nmax = 0
        nmax(1:D) = int(plan%q_max/dq(1:D))
        call phases(x(1, :), dq(1), nmax(1), ex)
        if (D >= 2) then
            call phases(x(2, :), dq(2), nmax(2), ey)
        else
            call unit_phases(natoms, ey)
        end if
        if (D >= 3) then
            call phases(x(3, :), dq(3), nmax(3), ez)
        else
            call unit_phases(natoms, ez)
        end if
        do n1 = 0, nmax(1)
            a1 = ex(:, n1)
            n2lo = merge(0, -nmax(2), n1 == 0)
            do n2 = n2lo, nmax(2)
                if ((n1*dq(1))**2 + (n2*dq(2))**2 > qmax2) cycle
                a12 = a1*ey(:, n2)
                n3lo = merge(-nmax(3), 1, n1 > 0 .or. n2 > 0)     ! half-space: n3 > 0 when n1 = n2 = 0
                do n3 = n3lo, nmax(3)
                    k3 = n3
                    q2 = (n1*dq(1))**2 + (n2*dq(2))**2 + (k3*dq(3))**2
                    if (q2 > qmax2 .or. q2 == 0) cycle
                    rho = (0.0_dp, 0.0_dp)
                    do j = 1, natoms
                        rho = rho + a12(j)*ez(j, k3)
                    end do
                    q = sqrt(q2)
                    b = int(q/plan%bin_width) + 1
                    ssum(b) = ssum(b) + (real(rho)**2 + aimag(rho)**2)/natoms
                    qsum(b) = qsum(b) + q
                    cnt(b) = cnt(b) + 1
                end do
            end do
        end do
    end subroutine add_frame_sq

    !> <prefix>_sq.csv (the bins with q vectors: mean |q|, S, q vectors per frame) and the summary.
    subroutine report_sq(traj, cfg, plan, ssum, qsum, cnt, frames_done)
        type(h5md_trajectory_t), intent(in) :: traj
        type(analysis_config_t), intent(in) :: cfg
        type(sq_plan_t), intent(in) :: plan
        real(dp), intent(in) :: ssum(:), qsum(:), cnt(:), frames_done
        real(dp), allocatable :: cols(:, :)
        character(len=:), allocatable :: il
        integer :: b, j, nused
        nused = count(cnt > 0)
        allocate (cols(nused, 3))
        j = 0
        do b = 1, plan%nbins
            if (cnt(b) == 0) cycle
            j = j + 1
            cols(j, :) = [qsum(b)/cnt(b), ssum(b)/cnt(b), cnt(b)/frames_done]
        end do
        il = '(1/'//trim(traj%unit_length)//')'
        if (len_trim(traj%unit_length) == 0) il = '(reduced)'
        call write_csv(trim(cfg%output_prefix)//'_sq.csv', 'q '//il//',S (1),q_vectors_per_frame (1)', cols)
        if (world%rank == 0) then
            write (output_unit, '(a)') 'S(q):'
            write (output_unit, '(a,i0,a,es12.5,a,es12.5,a,i0)') '  frames: ', int(frames_done), ' ; q_max = ', &
                plan%q_max, ' ; bin width ', plan%bin_width, ' ; q vectors per frame ', int(sum(cnt)/max(frames_done, 1.0_dp))
            if (nused > 0) then
                b = maxloc(cols(:, 2), 1)
                write (output_unit, '(a,es12.5,a,es12.5)') '  highest S(q) at q = ', cols(b, 1), ', S = ', cols(b, 2)
            end if
            write (output_unit, '(a)') '  wrote '//trim(cfg%output_prefix)//'_sq.csv'
        end if
    end subroutine report_sq

    !> p(j, n) = exp(i n dq x_j), n = -nm..nm, by repeated multiplication.
    subroutine phases(xc, dqc, nm, p)
        real(dp), intent(in) :: xc(:), dqc
        integer, intent(in) :: nm
        complex(dp), allocatable, intent(inout) :: p(:, :)
        integer :: n
        if (allocated(p)) deallocate (p)
        allocate (p(size(xc), -nm:nm))
        p(:, 0) = (1.0_dp, 0.0_dp)
        if (nm >= 1) p(:, 1) = cmplx(cos(dqc*xc), sin(dqc*xc), kind=dp)
        do n = 2, nm
            p(:, n) = p(:, n - 1)*p(:, 1)
        end do
        do n = 1, nm
            p(:, -n) = conjg(p(:, n))
        end do
    end subroutine phases

    subroutine unit_phases(n, p)
        integer(i8), intent(in) :: n
        complex(dp), allocatable, intent(inout) :: p(:, :)
        if (allocated(p)) deallocate (p)
        allocate (p(n, 0:0))
        p = (1.0_dp, 0.0_dp)
    end subroutine unit_phases

end module terrace_structure_factor
