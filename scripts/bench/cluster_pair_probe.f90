!> Probe for issue 16's mixed-precision goal: what a cluster-pair LJ force pass (GROMACS's nbnxm
!> idea: clusters of four atoms, one list of neighbouring clusters per cluster, all 4 x 4 pairs of
!> a cluster pair computed, 16 singles per AVX-512 vector) costs on LAMMPS's LJ bench scene, next to
!> the atom-pair list that Terrace's kernels use. Not part of the engine; built and run by
!> cluster_pair_probe.sh with the engine's optimisation flags.
!>
!> Scene: fcc, 20^3 cells, rho* 0.8442 (32,000 atoms), each coordinate displaced by a uniform
!> random amount in [-0.2, 0.2] sigma; rc 2.5 sigma; cluster lists built at a radius R (argument:
!> 2.8 = rc + LAMMPS's skin, the list every pass would read without pruning; 2.5 = rc, the fewest
!> cluster pairs that a pruned list could keep).
!> Clusters: the box cut into square columns of side (4/rho)^(1/3) (four atoms per cube of that
!> side), the atoms of each column sorted by z and taken four at a time (the last padded with far
!> away dummies). A cluster pair (ci < cj) is listed when the bounding boxes lie closer than R.
!> Positions are stored per cluster as singles relative to the cluster's box centre; a listed pair
!> carries the single-precision offset between the two centres (minimum image), so a separation
!> is formed from small numbers (about 1e-7 sigma round-off, as the mixed kernel's hi/lo pairs).
!> Force pass, per cluster ci: its neighbours' positions are staged end to end (offset added),
!> the pair loop runs 16 j atoms per vector against ci's four atoms (their forces summed in 16
!> lanes each), the j forces are summed into singles per staged atom and added to the double
!> per-cluster force records. Pairs within the same cluster: a scalar loop.
!> Output: pair counts, the pass's CPU time, and that time without the pair loop (staging and
!> write-back alone), best of several repetitions; forces checked against a double reference.
program cluster_pair_probe
    use, intrinsic :: iso_fortran_env, only: dp => real64, sp => real32, error_unit
    implicit none
    integer, parameter :: nc = 20, natoms = 4*nc**3, jmax = 4096
    real(dp), parameter :: rho = 0.8442_dp, rc = 2.5_dp
    real(dp) :: x(3, natoms), fref(3, natoms), L, a, radius, frms, err
    integer :: npair_rc, npair_list, ncl, nlisted, i, k, rep, pass, npass
    real(sp), allocatable :: xr(:, :, :), offs(:, :)
    real(dp), allocatable :: f4(:, :, :), centre(:, :), half(:, :)
    integer, allocatable :: member(:, :), cfirst(:), clist(:)
    real(dp) :: t0, t1, best_full, best_skip
    character(len=32) :: arg

    radius = 2.8_dp
    if (command_argument_count() > 0) then
        call get_command_argument(1, arg); read (arg, *) radius
    end if
    ! the search covers two columns either side (2 x 1.68 sigma) and at most 100 clusters per list
    if (.not. (radius >= rc .and. radius <= 3.0_dp)) then
        write (error_unit, '(a)') 'cluster_pair_probe: the list radius must be in [2.5, 3.0] sigma'
        stop 2
    end if
    a = (4/rho)**(1.0_dp/3); L = nc*a
    call lattice(x)
    call reference(x, fref, npair_rc, npair_list)
    frms = sqrt(sum(fref**2)/natoms)
    call build(x, radius, ncl, xr, member, centre, half, cfirst, clist, offs, nlisted)
    allocate (f4(4, 3, ncl))
    npass = 20
    best_full = huge(1.0_dp); best_skip = huge(1.0_dp)
    do rep = 1, 5
        call cpu_time(t0)
        do pass = 1, npass
            call force_pass(ncl, xr, cfirst, clist, offs, f4, .false.)
        end do
        call cpu_time(t1); best_full = min(best_full, (t1 - t0)/npass)
        call cpu_time(t0)
        do pass = 1, npass
            call force_pass(ncl, xr, cfirst, clist, offs, f4, .true.)
        end do
        call cpu_time(t1); best_skip = min(best_skip, (t1 - t0)/npass)
    end do
    call force_pass(ncl, xr, cfirst, clist, offs, f4, .false.)
    err = 0
    do i = 1, ncl
        do k = 1, 4
            if (member(k, i) > 0) err = max(err, maxval(abs(f4(k, :, i) - fref(:, member(k, i)))))
        end do
    end do
    print '(a, f5.2, a, i0, a, i0)', 'cluster list radius ', radius, ' sigma; clusters ', ncl, '; atoms ', natoms
    print '(a, i0, a, f6.2, a)', 'atom pairs within rc + skin (2.8): ', npair_list, ' (', real(npair_list, dp)/natoms, ' per atom)'
    print '(a, i0, a, f6.2, a)', 'atom pairs within rc (2.5):        ', npair_rc, ' (', real(npair_rc, dp)/natoms, ' per atom)'
    print '(a, i0, a, f6.2, a, f5.2, a, f5.2, a)', 'cluster pairs listed: ', nlisted, ' (', real(nlisted, dp)/ncl, &
        ' per cluster); pairs computed per pair within rc + skin ', 16*real(nlisted, dp)/npair_list, ', within rc ', &
        16*real(nlisted, dp)/npair_rc
    print '(a, f7.3, a, f6.3, a)', 'force pass (best of 5 x 20): ', 1e3*best_full, ' ms CPU; ', &
        1e9*best_full/npair_list, ' ns per pair within rc + skin'
    print '(a, f7.3, a, f7.3, a, f6.3, a)', '  staging and write-back alone: ', 1e3*best_skip, ' ms; pair loop (difference): ', &
        1e3*(best_full - best_skip), ' ms, ', 1e9*(best_full - best_skip)/(16*real(nlisted, dp)), ' ns per computed pair'
    print '(a, f7.3, a)', '  per listed cluster pair: staging and write-back ', 1e9*best_skip/nlisted, ' ns'
    print '(a, es9.2, a)', 'max |F - F_double| / F_rms: ', err/frms, ' (double reference, minimum image, all pairs)'

contains

    !> fcc lattice, every coordinate displaced by a uniform amount in [-0.2, 0.2] sigma (a
    !> linear congruential sequence, so every run sees the same atoms)
    subroutine lattice(x)
        real(dp), intent(out) :: x(:, :)
        integer :: ix, iy, iz, b, n
        integer(8) :: seed
        real(dp), parameter :: basis(3, 4) = reshape([0, 0, 0, 1, 1, 0, 1, 0, 1, 0, 1, 1], [3, 4])*0.5_dp
        seed = 12345
        n = 0
        do iz = 0, nc - 1
            do iy = 0, nc - 1
                do ix = 0, nc - 1
                    do b = 1, 4
                        n = n + 1
                        x(:, n) = a*([ix, iy, iz] + basis(:, b)) + 0.4_dp*[uniform(seed), uniform(seed), uniform(seed)]
                        x(:, n) = modulo(x(:, n), L)
                    end do
                end do
            end do
        end do
    end subroutine lattice

    real(dp) function uniform(seed) result(u)
        integer(8), intent(inout) :: seed
        seed = modulo(seed*6364136223846793005_8 + 1442695040888963407_8, huge(seed))
        u = real(modulo(seed/1024, 1048576_8), dp)/1048576 - 0.5_dp
    end function uniform

    !> Forces of all pairs within rc in double precision (minimum image), and the pair counts
    subroutine reference(x, f, nrc, nlist)
        real(dp), intent(in) :: x(:, :)
        real(dp), intent(out) :: f(:, :)
        integer, intent(out) :: nrc, nlist
        integer :: i, j
        real(dp) :: d(3), r2, r6, fp
        f = 0; nrc = 0; nlist = 0
        do i = 1, natoms
            do j = i + 1, natoms
                d = x(:, i) - x(:, j); d = d - L*anint(d/L)
                r2 = d(1)*d(1) + d(2)*d(2) + d(3)*d(3)
                if (r2 < 2.8_dp**2) nlist = nlist + 1
                if (r2 < rc*rc) then
                    nrc = nrc + 1
                    r6 = 1/(r2*r2*r2)
                    fp = r6*(48*r6 - 24)/r2
                    f(:, i) = f(:, i) + fp*d; f(:, j) = f(:, j) - fp*d
                end if
            end do
        end do
    end subroutine reference

    !> Clusters and the half list of cluster pairs whose bounding boxes lie within radius
    subroutine build(x, radius, ncl, xr, member, centre, half, cfirst, clist, offs, nlisted)
        real(dp), intent(in) :: x(:, :), radius
        integer, intent(out) :: ncl, nlisted
        real(sp), allocatable, intent(out) :: xr(:, :, :), offs(:, :)
        integer, allocatable, intent(out) :: member(:, :), cfirst(:), clist(:)
        real(dp), allocatable, intent(out) :: centre(:, :), half(:, :)
        integer :: ncx, c, i, k, m, kk, ci, cj, dx, dy, cx, cy, p
        integer, allocatable :: count(:), start(:), idx(:), col(:), c0(:)
        real(dp) :: w, d(3), s(3), lo(3), hi(3)
        ncx = int(L/(4/rho)**(1.0_dp/3)); w = L/ncx
        allocate (count(ncx*ncx), start(ncx*ncx + 1), idx(natoms), col(natoms), c0(ncx*ncx + 1))
        count = 0
        do i = 1, natoms
            col(i) = 1 + min(ncx - 1, int(x(1, i)/w)) + ncx*min(ncx - 1, int(x(2, i)/w))
            count(col(i)) = count(col(i)) + 1
        end do
        start(1) = 1
        do c = 1, ncx*ncx
            start(c + 1) = start(c) + count(c)
        end do
        count = 0
        do i = 1, natoms
            idx(start(col(i)) + count(col(i))) = i; count(col(i)) = count(col(i)) + 1
        end do
        do c = 1, ncx*ncx            ! each column by z (insertion sort)
            do k = start(c) + 1, start(c + 1) - 1
                m = idx(k); kk = k - 1
                do while (kk >= start(c))
                    if (x(3, idx(kk)) <= x(3, m)) exit
                    idx(kk + 1) = idx(kk); kk = kk - 1
                end do
                idx(kk + 1) = m
            end do
        end do
        ncl = 0
        do c = 1, ncx*ncx
            c0(c) = ncl + 1
            ncl = ncl + (count(c) + 3)/4
        end do
        c0(ncx*ncx + 1) = ncl + 1
        allocate (xr(4, 3, ncl), member(4, ncl), centre(3, ncl), half(3, ncl))
        do c = 1, ncx*ncx
            do ci = c0(c), c0(c + 1) - 1
                lo = huge(1.0_dp); hi = -huge(1.0_dp)
                do k = 1, 4
                    p = start(c) + 4*(ci - c0(c)) + k - 1
                    member(k, ci) = 0
                    if (p < start(c + 1)) then
                        member(k, ci) = idx(p)
                        lo = min(lo, x(:, idx(p))); hi = max(hi, x(:, idx(p)))
                    end if
                end do
                centre(:, ci) = 0.5_dp*(lo + hi); half(:, ci) = 0.5_dp*(hi - lo)
                do k = 1, 4
                    xr(k, :, ci) = 300          ! dummies: beyond the cutoff from every atom
                    if (member(k, ci) > 0) xr(k, :, ci) = real(x(:, member(k, ci)) - centre(:, ci), sp)
                end do
            end do
        end do
        allocate (cfirst(ncl + 1), clist(ncl*100), offs(4, ncl*100))
        nlisted = 0
        do c = 1, ncx*ncx
            cx = mod(c - 1, ncx); cy = (c - 1)/ncx
            do ci = c0(c), c0(c + 1) - 1
                cfirst(ci) = nlisted + 1
                do dy = -2, 2
                    do dx = -2, 2
                        m = 1 + modulo(cx + dx, ncx) + ncx*modulo(cy + dy, ncx)
                        do cj = c0(m), c0(m + 1) - 1
                            if (cj <= ci) cycle
                            d = centre(:, cj) - centre(:, ci)
                            s = -L*anint(d/L)
                            d = max(abs(d + s) - half(:, ci) - half(:, cj), 0.0_dp)
                            if (d(1)*d(1) + d(2)*d(2) + d(3)*d(3) < radius*radius) then
                                nlisted = nlisted + 1
                                clist(nlisted) = cj
                                offs(1:3, nlisted) = real(centre(:, cj) + s - centre(:, ci), sp)
                                offs(4, nlisted) = 0
                            end if
                        end do
                    end do
                end do
            end do
        end do
        cfirst(ncl + 1) = nlisted + 1
    end subroutine build

    !> One force pass (forces only) into f4(atom in cluster, component, cluster); skip_pairs: the
    !> staging and write-back alone
    subroutine force_pass(ncl, xr, cfirst, clist, offs, f4, skip_pairs)
        integer, intent(in) :: ncl, cfirst(ncl + 1), clist(*)
        real(sp), intent(in) :: xr(4, 3, ncl), offs(4, *)
        real(dp), intent(out) :: f4(4, 3, ncl)
        logical, intent(in) :: skip_pairs
        real(sp) :: xs(jmax), ys(jmax), zs(jmax), fxs(jmax), fys(jmax), fzs(jmax)
        real(sp) :: ax(16, 4), ay(16, 4), az(16, 4), xi(4), yi(4), zi(4)
        real(sp) :: dx, dy, dz, r2, r2i, r6, fp, gx, gy, gz, cut
        real(dp) :: t4(4)
        integer :: ci, cj, p, n, m, k, kb, l, ii, jj
        cut = real(rc*rc, sp)
        f4 = 0
        do ci = 1, ncl
            xi = xr(:, 1, ci); yi = xr(:, 2, ci); zi = xr(:, 3, ci)
            n = 0
            !GCC$ novector
            do p = cfirst(ci), cfirst(ci + 1) - 1
                cj = clist(p)
                xs(n + 1:n + 4) = xr(:, 1, cj) + offs(1, p)
                ys(n + 1:n + 4) = xr(:, 2, cj) + offs(2, p)
                zs(n + 1:n + 4) = xr(:, 3, cj) + offs(3, p)
                n = n + 4
            end do
            m = (n + 15)/16*16
            xs(n + 1:m) = 300; ys(n + 1:m) = 0; zs(n + 1:m) = 0
            ax = 0; ay = 0; az = 0
            if (skip_pairs) then
                fxs(1:n) = xs(1:n); fys(1:n) = ys(1:n); fzs(1:n) = zs(1:n)
            else
                do kb = 0, m - 16, 16
                    do l = 1, 16
                        k = kb + l
                        gx = 0; gy = 0; gz = 0
                        do ii = 1, 4        ! (unrolled by GCC: four lanes of i accumulators)
                            dx = xi(ii) - xs(k); dy = yi(ii) - ys(k); dz = zi(ii) - zs(k)
                            r2 = dx*dx + dy*dy + dz*dz
                            r2i = (0.5_sp + sign(0.5_sp, cut - r2))/r2
                            r6 = r2i*r2i*r2i; fp = r6*(48*r6 - 24)*r2i
                            ax(l, ii) = ax(l, ii) + fp*dx; ay(l, ii) = ay(l, ii) + fp*dy; az(l, ii) = az(l, ii) + fp*dz
                            gx = gx - fp*dx; gy = gy - fp*dy; gz = gz - fp*dz
                        end do
                        fxs(k) = gx; fys(k) = gy; fzs(k) = gz
                    end do
                end do
            end if
            n = 0
            !GCC$ novector
            do p = cfirst(ci), cfirst(ci + 1) - 1
                cj = clist(p)
                t4 = real(fxs(n + 1:n + 4), dp); f4(:, 1, cj) = f4(:, 1, cj) + t4
                t4 = real(fys(n + 1:n + 4), dp); f4(:, 2, cj) = f4(:, 2, cj) + t4
                t4 = real(fzs(n + 1:n + 4), dp); f4(:, 3, cj) = f4(:, 3, cj) + t4
                n = n + 4
            end do
            do ii = 1, 4
                f4(ii, :, ci) = f4(ii, :, ci) + [sum(real(ax(:, ii), dp)), sum(real(ay(:, ii), dp)), sum(real(az(:, ii), dp))]
            end do
            do ii = 1, 3            ! pairs within the cluster
                do jj = ii + 1, 4
                    dx = xi(ii) - xi(jj); dy = yi(ii) - yi(jj); dz = zi(ii) - zi(jj)
                    r2 = dx*dx + dy*dy + dz*dz
                    if (r2 < cut) then
                        r6 = 1/(r2*r2*r2); fp = r6*(48*r6 - 24)/r2
                        f4(ii, :, ci) = f4(ii, :, ci) + fp*[dx, dy, dz]
                        f4(jj, :, ci) = f4(jj, :, ci) - fp*[dx, dy, dz]
                    end if
                end do
            end do
        end do
    end subroutine force_pass

end program cluster_pair_probe
