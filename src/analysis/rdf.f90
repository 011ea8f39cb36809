!> Radial distribution function g(r) and the running coordination number n(r).
!>
!> Pairs i < j of every selected frame (every rdf_every-th) are binned by distance, with the
!> minimum-image convention in the periodic dimensions (d - L nint(d / L)) and plain differences in
!> the others. Normalisation:
!>   periodic box (every dimension periodic; needs r_max <= L/2 for each edge):
!>       g(r) = <V h(r)> / ( N (N-1)/2 * V_shell(r) ),   V_shell = shell volume (area in 2-D)
!>       so that g = 1 for uncorrelated positions; V is the box volume of each frame.
!>   free cluster (any dimension not periodic): the pair-distance density
!>       p(r) = <h(r)> / ( N (N-1)/2 * dr ),   so that int_0^inf p(r) dr = 1 (pairs beyond r_max
!>       are counted in the denominator, not in the histogram).
!>   both: n(r) = 2 <H(r)> / N, the mean number of neighbours within r (H: pairs closer than the
!>       upper edge of the bin).
!> Parallel over frames (a contiguous block of the selected frames per rank, read in batches),
!> one reduction of the histograms.
module terrace_rdf
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

    type, public, extends(frame_plan_t) :: rdf_plan_t
        real(dp) :: r_max = 0
        logical :: periodic_box = .false.
    end type rdf_plan_t

    public :: plan_rdf, run_rdf, pair_histogram


contains

    subroutine plan_rdf(traj, cfg, plan)
        type(h5md_trajectory_t), intent(in) :: traj
        type(analysis_config_t), intent(in) :: cfg
        type(rdf_plan_t), intent(out) :: plan
        integer(i8) :: k
        integer :: d
        real(dp) :: half, e(3)
        real(dp), allocatable :: x(:, :, :)
        character(len=32) :: a
        call frame_window(cfg, traj%frames(el_position), traj%where('position/value'), cfg%rdf_every, plan)
        call check_all(traj%natoms >= 2, traj%where('position/value')//': g(r) needs at least two atoms')
        d = traj%dimension
        plan%periodic_box = all(traj%periodic(1:d))
        if (plan%periodic_box) then
            half = huge(1.0_dp)
            do k = 1, plan%nsel
                e = traj%box_edges(plan%f0 + 1 + (k - 1)*plan%stride)
                half = min(half, 0.5_dp*minval(e(1:d)))
            end do
            if (is_unset(cfg%rdf_r_max)) then
                plan%r_max = half
            else
                plan%r_max = cfg%rdf_r_max
                write (a, '(es12.5)') half
                call check_all(plan%r_max <= half*(1 + 1.0e-12_dp), cfg%where('rdf_r_max')//': larger than half '// &
                               'the shortest box edge of '//traj%path//' ('//trim(adjustl(a))//'; the minimum image '// &
                               'is unique only within it)')
            end if
        else if (is_unset(cfg%rdf_r_max)) then
            ! free cluster: 1.5 times the largest pair distance of the first selected frame
            allocate (x(d, traj%natoms, 1))
            call traj%read_real(el_position, plan%f0, 1_i8, 1_i8, 0_i8, traj%natoms, x)
            plan%r_max = 1.5_dp*largest_distance(x(:, :, 1), traj%box_edges(plan%f0 + 1), traj%periodic)
            call check_all(plan%r_max > 0, traj%where('position/value')//': every atom at the same place')
        else
            plan%r_max = cfg%rdf_r_max
        end if
    end subroutine plan_rdf

    real(dp) function largest_distance(x, edges, periodic) result(r)
        real(dp), intent(in) :: x(:, :), edges(3)
        logical, intent(in) :: periodic(3)
        integer :: i, j
        real(dp) :: L(3), invL(3), dx(3)
        L = 0; invL = 0
        where (periodic)
            L = edges; invL = 1/edges
        end where
        r = 0
        do j = 2, size(x, 2)
            do i = 1, j - 1
                dx(1:size(x, 1)) = x(:, j) - x(:, i)
                dx(1:size(x, 1)) = dx(1:size(x, 1)) - L(1:size(x, 1))*anint(dx(1:size(x, 1))*invL(1:size(x, 1)))
                r = max(r, norm2(dx(1:size(x, 1))))
            end do
        end do
    end function largest_distance

    !> h(b) += number of pairs i < j of x(1:D, 1:n) at distance in bin b (width r_max/nbins); L and
    !> invL are the periodic edges and their inverses (0 for non-periodic dimensions).
    subroutine pair_histogram(x, L, invL, r_max, h)
        real(dp), intent(in) :: x(:, :), L(3), invL(3), r_max
        real(dp), intent(inout) :: h(:)
        integer :: i, j, n, D
        real(dp) :: dx, dy, dz, r2, rmax2, scale
        n = size(x, 2); D = size(x, 1)
        rmax2 = r_max*r_max
        scale = size(h)/r_max
        select case (D)
        case (3)
            do j = 2, n
                do i = 1, j - 1
                    dx = x(1, j) - x(1, i); dx = dx - L(1)*anint(dx*invL(1))
                    dy = x(2, j) - x(2, i); dy = dy - L(2)*anint(dy*invL(2))
                    dz = x(3, j) - x(3, i); dz = dz - L(3)*anint(dz*invL(3))
                    r2 = dx*dx + dy*dy + dz*dz
                    if (r2 < rmax2) call count_pair(r2, scale, h)
                end do
            end do
        case (2)
            do j = 2, n
                do i = 1, j - 1
                    dx = x(1, j) - x(1, i); dx = dx - L(1)*anint(dx*invL(1))
                    dy = x(2, j) - x(2, i); dy = dy - L(2)*anint(dy*invL(2))
                    r2 = dx*dx + dy*dy
                    if (r2 < rmax2) call count_pair(r2, scale, h)
                end do
            end do
        case default
            do j = 2, n
                do i = 1, j - 1
                    dx = x(1, j) - x(1, i); dx = dx - L(1)*anint(dx*invL(1))
                    r2 = dx*dx
                    if (r2 < rmax2) call count_pair(r2, scale, h)
                end do
            end do
        end select
    end subroutine pair_histogram

    !> One pair at squared distance r2 (< r_max^2) into its bin of h (scale = bins per length).
    pure subroutine count_pair(r2, scale, h)
        real(dp), intent(in) :: r2, scale
        real(dp), intent(inout) :: h(:)
        integer :: b
        b = min(int(sqrt(r2)*scale) + 1, size(h))
        h(b) = h(b) + 1
    end subroutine count_pair

    subroutine run_rdf(traj, cfg, plan)
        type(h5md_trajectory_t), intent(in) :: traj
        type(analysis_config_t), intent(in) :: cfg
        type(rdf_plan_t), intent(in) :: plan
        real(dp), allocatable :: x(:, :, :), h(:), hv(:), cum(:), cols(:, :)
        real(dp) :: L(3), invL(3), e(3), vol, dr, npairs, r1, r2, shell, g, frames_done(1)
        integer(i8) :: k, fr, k0, nk, kb, batch, nread
        integer :: b, D, nb
        character(len=:), allocatable :: ll

        D = traj%dimension; nb = cfg%rdf_bins
        dr = plan%r_max/nb
        ! this rank's contiguous block of the selected frames, read in batches of up to ~32 MiB
        call id_block(plan%nsel, world%nprocs, world%rank, k0, nk)
        k0 = k0 - 1          ! 0-based start of this rank's block
        batch = max(1_i8, min(nk, batch_values/(D*traj%natoms)))
        allocate (x(D, traj%natoms, batch), h(nb), hv(nb), cum(nb))
        hv = 0; cum = 0
        frames_done = 0
        do kb = 1, nk, batch
            nread = min(batch, nk - kb + 1)
            call traj%read_real(el_position, plan%f0 + (k0 + kb - 1)*plan%stride, nread, plan%stride, 0_i8, &
                                traj%natoms, x(:, :, 1:nread))
          do k = 1, nread
            fr = plan%f0 + (k0 + kb - 1 + k - 1)*plan%stride
            e = traj%box_edges(fr + 1)
            L = 0; invL = 0
            where (traj%periodic)
                L = e; invL = 1/e
            end where
            vol = product(e(1:D))
            h = 0
            call pair_histogram(x(:, :, k), L, invL, plan%r_max, h)
            cum = cum + h
            if (plan%periodic_box) hv = hv + vol*h
            frames_done = frames_done + 1
          end do
        end do
        call sum_all(cum)
        call sum_all(hv)
        call sum_all(frames_done)
        npairs = 0.5_dp*real(traj%natoms, dp)*real(traj%natoms - 1, dp)
        allocate (cols(nb, 3))
        g = 0
        do b = 1, nb
            r1 = (b - 1)*dr; r2 = b*dr
            select case (D)
            case (3); shell = 4*pi/3*(r2**3 - r1**3)
            case (2); shell = pi*(r2**2 - r1**2)
            case default; shell = 2*(r2 - r1)
            end select
            if (plan%periodic_box) then
                cols(b, 2) = hv(b)/(frames_done(1)*npairs*shell)
            else
                cols(b, 2) = cum(b)/(frames_done(1)*npairs*dr)
            end if
            g = g + cum(b)
            cols(b, 1) = (b - 0.5_dp)*dr
            cols(b, 3) = 2*g/(frames_done(1)*traj%natoms)
        end do
        ll = unit_label(traj%unit_length)
        if (plan%periodic_box) then
            call write_csv(trim(cfg%output_prefix)//'_rdf.csv', 'r '//ll//',g (1),n_cumulative (1)', cols)
        else
            if (len_trim(traj%unit_length) > 0) ll = '(1/'//trim(traj%unit_length)//')'
            call write_csv(trim(cfg%output_prefix)//'_rdf.csv', 'r '//unit_label(traj%unit_length)//',pair_density '// &
                           ll//',n_cumulative (1)', cols)
        end if
        if (world%rank == 0) then
            write (output_unit, '(a)') 'g(r):'
            write (output_unit, '(a,i0,a,es12.5,a,i0,a)') '  frames: ', int(frames_done(1)), ' ; r_max = ', plan%r_max, &
                ' ; ', nb, ' bins'
            if (plan%periodic_box) then
                b = maxloc(cols(:, 2), 1)
                write (output_unit, '(a,es12.5,a,es12.5)') '  periodic box: highest maximum of g(r) at r = ', cols(b, 1), &
                    ', g = ', cols(b, 2)
            else
                write (output_unit, '(a)') '  free (non-periodic) box: pair-distance density p(r), int p dr = 1'
            end if
            write (output_unit, '(a)') '  wrote '//trim(cfg%output_prefix)//'_rdf.csv'
        end if
    end subroutine run_rdf

end module terrace_rdf
