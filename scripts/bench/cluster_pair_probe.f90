!> Probe for the mixed-precision goal: what a cluster-pair LJ force pass (GROMACS's nbnxm
!> idea: clusters of four atoms, one list of neighbouring clusters per cluster, all 4 x 4 pairs of
!> a cluster pair computed, 16 singles per AVX-512 vector) costs on LAMMPS's LJ bench scene, next to
!> the atom-pair list that Terrace's kernels use. Not part of the engine; built and run by
!> cluster_pair_probe.sh with the engine's optimisation flags.
!>
!> Scene: LAMMPS's LJ bench box (32,000 atoms, rho* 0.8442, rc 2.5 sigma): by default an fcc
!> lattice of 20^3 cells, each coordinate displaced by a uniform random amount in [-0.2, 0.2]
!> sigma; or the atoms of a Terrace final-state file (the fourth argument). Arguments: the list
!> radius R (2.8 = rc + LAMMPS's skin, the list every pass would read without pruning; 2.5 = rc,
!> the fewest cluster pairs that a pruned list could keep), and 'atoms' to list a cluster pair only
!> when one of its 16 atom pairs lies within R (GROMACS's check after the bounding boxes), else
!> ('boxes') bounding boxes only;
!> a third, rin < R, prunes the list built at R to the cluster pairs with an atom pair within rin
!> (GROMACS's dynamic pruning: an outer list that lives longer, an inner one re-pruned from it;
!> the prune is timed and the passes run over the inner list; 0: none); a fourth, a Terrace
!> final-state file of the same scene (&output final_atoms_file), takes its atoms instead of the
!> displaced lattice.
!> Clusters: the box cut into square columns of side (4/rho)^(1/3) (four atoms per cube of that
!> side), the atoms of each column sorted by z and taken four at a time (the last padded with far
!> away dummies). Each cluster pair once: ci's own column (cj > ci) and the 12 columns of the half
!> stencil ahead of it. cj is a candidate when its z extent meets ci's widened by R (the columns
!> are z-sorted: a pointer that only moves up as ci does; bisection for the periodic images above
!> and below), and listed when the bounding boxes lie closer than R (and, with 'atoms', an atom
!> pair does). Positions are stored per cluster as singles relative to the cluster's centre (the
!> centres on a grid of 2^-10 sigma); a listed pair carries the offset between the two centres
!> (minimum image; exact in single precision), so a separation is formed from small numbers.
!> Four force passes, timed (wall clock, as Terrace's run log; best of 5 x 20), forces checked
!> against a double reference:
!> - staged: per cluster ci, its neighbours' positions copied end to end (offset added), the pair
!>   loop over 16 j atoms per vector against ci's four atoms, the j forces summed into singles per
!>   staged atom and added to double per-cluster records; timed also without its pair loop.
!> - replicated, j forces in singles: no staging. Every cluster's positions are kept replicated,
!>   lane l of 16 holding atom mod(l - 1, 4) + 1 (j0 j1 j2 j3 j0 ...), ci's atoms spread as
!>   (i0 i0 i0 i0 i1 ...), so one listed cluster pair is one 16-lane loop over contiguous records;
!>   j forces added to the j cluster's replicated single-precision force record, reduced over the
!>   four replicas into doubles at the end of the pass. Forming the replicas and the reduction are
!>   inside the timed pass (an engine would do both every step).
!> - replicated, j forces in doubles: the same with double j records (16 doubles per component).
!> - replicated, hi/lo separations, j forces in singles: each relative position carried as two
!>   singles, hi on the centres' 2^-10 grid and lo the rest, so that (hi_i - off) - hi_j is exact
!>   and a separation is rounded once, as in Terrace's mixed kernel (whose forces the probe also
!>   emulates: double separations rounded to single, single pair terms, double sums).
!> Force errors: max over atoms of |F - F_double| / rms F, leaving out the atoms with a pair within
!> 1e-6 sigma of the cutoff (single and double precision may decide such a pair differently, and the
!> truncated force jumps there by 0.039; the count is printed).
!> The list build (columns, clusters, list) is timed too (best of 3). Pairs within one cluster: a
!> scalar loop in each pass.
program cluster_pair_probe
    use, intrinsic :: iso_fortran_env, only: dp => real64, sp => real32, int64, error_unit
    implicit none
    integer, parameter :: nc = 20, natoms = 4*nc**3, jmax = 4096
    real(dp), parameter :: rho = 0.8442_dp, rc = 2.5_dp
    logical :: edge(natoms)
    real(dp) :: x(3, natoms), fref(3, natoms), fmix(3, natoms), L, a, radius, frms, err
    integer :: npair_rc, npair_list, ncl, nlisted, i, k, rep, pass, npass
    real(sp), allocatable :: xr(:, :, :), offs(:, :)
    real(dp), allocatable :: f4(:, :, :), centre(:, :), half(:, :)
    integer, allocatable :: member(:, :), cfirst(:), clist(:)
    real(dp) :: t0, t1, best_full, best_skip, best_rep(3), err_rep(3), best_build
    logical :: atom_check
    real(dp) :: rin, best_prune
    integer :: nouter
    integer, allocatable :: cfirst_in(:), clist_in(:)
    real(sp), allocatable :: offs_in(:, :)
    real(sp), allocatable :: xrep(:, :, :), frep_s(:, :, :), xrl(:, :, :), xrepl(:, :, :), xrh(:, :, :)
    real(dp), allocatable :: frep_d(:, :, :)
    integer :: v
    character(len=32) :: arg
    character(len=512) :: atoms_file

    radius = 2.8_dp
    if (command_argument_count() > 0) then
        call get_command_argument(1, arg); read (arg, *) radius
    end if
    atom_check = .false.
    if (command_argument_count() > 1) then
        call get_command_argument(2, arg); atom_check = trim(arg) == 'atoms'   ! (else 'boxes')
    end if
    rin = 0
    if (command_argument_count() > 2) then
        call get_command_argument(3, arg); read (arg, *) rin
    end if
    atoms_file = ''
    if (command_argument_count() > 3) call get_command_argument(4, atoms_file)
    ! the search covers two columns either side (2 x 1.68 sigma: any radius below 3.36)
    if (.not. (radius >= rc .and. radius <= 3.3_dp)) then
        write (error_unit, '(a)') 'cluster_pair_probe: the list radius must be in [2.5, 3.3] sigma'
        stop 2
    end if
    if (rin /= 0 .and. .not. (rin >= rc .and. rin < radius)) then
        write (error_unit, '(a)') 'cluster_pair_probe: the pruning radius must be in [2.5, list radius)'
        stop 2
    end if
    a = (4/rho)**(1.0_dp/3); L = nc*a
    if (len_trim(atoms_file) > 0) then
        call read_atoms(trim(atoms_file), x)
    else
        call lattice(x)
    end if
    call reference(x, fref, npair_rc, npair_list, fmix, edge)
    frms = sqrt(sum(fref**2)/natoms)
    print '(a, i0, a)', 'force errors below: max over atoms, leaving out the ', count(edge), &
        ' with a pair within 1e-6 sigma of the cutoff (single precision may decide it either way)'
    print '(a, es9.2)', 'Terrace''s mixed kernel emulated (double separations rounded to single): max |F - F_double| / F_rms ', &
        maxval(abs(fmix - fref), mask=spread(.not. edge, 1, 3))/frms
    best_build = huge(1.0_dp)
    do rep = 1, 3
        t0 = wall()
        call build(x, radius, ncl, xr, member, centre, half, cfirst, clist, offs, nlisted)
        t1 = wall(); best_build = min(best_build, t1 - t0)
    end do
    print '(a, f5.2, a, i0, a, i0)', 'cluster list radius ', radius, ' sigma; clusters ', ncl, '; atoms ', natoms
    print '(a, l1, a, f7.3, a)', 'cluster pairs checked atom by atom: ', atom_check, '; build (columns, clusters, list; best of 3): ', &
        1e3*best_build, ' ms'
    if (rin > 0) then
        ! dynamic pruning (GROMACS's inner list): the pairs of the list just built, kept when one
        ! of their 16 atom pairs lies within rin; the passes below then run over the pruned list
        best_prune = huge(1.0_dp)
        nouter = nlisted
        do rep = 1, 5
            t0 = wall()
            call prune(ncl, xr, cfirst, clist, offs, rin, cfirst_in, clist_in, offs_in, nlisted)
            t1 = wall(); best_prune = min(best_prune, t1 - t0)
        end do
        print '(a, f5.2, a, f5.2, a, i0, a, i0, a, f7.3, a)', 'pruned from ', radius, ' to ', rin, ' sigma: ', nouter, &
            ' cluster pairs to ', nlisted, '; prune pass (best of 5) ', 1e3*best_prune, ' ms'
        call move_alloc(cfirst_in, cfirst); call move_alloc(clist_in, clist); call move_alloc(offs_in, offs)
        radius = rin
    end if
    allocate (f4(4, 3, ncl))
    npass = 20
    best_full = huge(1.0_dp); best_skip = huge(1.0_dp)
    do rep = 1, 5
        t0 = wall()
        do pass = 1, npass
            call force_pass(ncl, xr, cfirst, clist, offs, f4, .false.)
        end do
        t1 = wall(); best_full = min(best_full, (t1 - t0)/npass)
        t0 = wall()
        do pass = 1, npass
            call force_pass(ncl, xr, cfirst, clist, offs, f4, .true.)
        end do
        t1 = wall(); best_skip = min(best_skip, (t1 - t0)/npass)
    end do
    call force_pass(ncl, xr, cfirst, clist, offs, f4, .false.)
    err = 0
    do i = 1, ncl
        do k = 1, 4
            if (member(k, i) > 0) then
                if (.not. edge(member(k, i))) err = max(err, maxval(abs(f4(k, :, i) - fref(:, member(k, i)))))
            end if
        end do
    end do
    allocate (xrep(16, 3, ncl), frep_s(16, 3, ncl), frep_d(16, 3, ncl), xrl(4, 3, ncl), xrepl(16, 3, ncl))
    ! hi/lo: hi = the relative position on the 2^-10 grid of the centres (so that hi_i - off - hi_j
    ! is exact in single), lo = the rest (below 2^-11 sigma, its rounding below 1e-10 sigma)
    xrh = xr
    do i = 1, ncl
        do k = 1, 4
            xrl(k, :, i) = 0
            if (member(k, i) > 0) then
                xrh(k, :, i) = real(anint((x(:, member(k, i)) - centre(:, i))*1024)/1024, sp)
                xrl(k, :, i) = real(x(:, member(k, i)) - centre(:, i) - real(xrh(k, :, i), dp), sp)
            end if
        end do
    end do
    best_rep = huge(1.0_dp)
    do rep = 1, 5
        do v = 1, 3
            t0 = wall()
            do pass = 1, npass
                if (v == 1) call force_pass_rep_s(ncl, xr, cfirst, clist, offs, f4, xrep, frep_s)
                if (v == 2) call force_pass_rep_d(ncl, xr, cfirst, clist, offs, f4, xrep, frep_d)
                if (v == 3) call force_pass_rep_hl(ncl, xrh, xrl, cfirst, clist, offs, f4, xrep, xrepl, frep_s)
            end do
            t1 = wall(); best_rep(v) = min(best_rep(v), (t1 - t0)/npass)
        end do
    end do
    do v = 1, 3
        if (v == 1) call force_pass_rep_s(ncl, xr, cfirst, clist, offs, f4, xrep, frep_s)
        if (v == 2) call force_pass_rep_d(ncl, xr, cfirst, clist, offs, f4, xrep, frep_d)
        if (v == 3) call force_pass_rep_hl(ncl, xrh, xrl, cfirst, clist, offs, f4, xrep, xrepl, frep_s)
        err_rep(v) = 0
        do i = 1, ncl
            do k = 1, 4
                if (member(k, i) > 0) then
                    if (.not. edge(member(k, i))) err_rep(v) = max(err_rep(v), maxval(abs(f4(k, :, i) - fref(:, member(k, i)))))
                end if
            end do
        end do
    end do
    print '(a, i0, a, f6.2, a)', 'atom pairs within rc + skin (2.8): ', npair_list, ' (', real(npair_list, dp)/natoms, ' per atom)'
    print '(a, i0, a, f6.2, a)', 'atom pairs within rc (2.5):        ', npair_rc, ' (', real(npair_rc, dp)/natoms, ' per atom)'
    print '(a, i0, a, f6.2, a, f5.2, a, f5.2, a)', 'cluster pairs in the passes'' list: ', nlisted, ' (', real(nlisted, dp)/ncl, &
        ' per cluster); pairs computed per pair within rc + skin ', 16*real(nlisted, dp)/npair_list, ', within rc ', &
        16*real(nlisted, dp)/npair_rc
    print '(a, f7.3, a, f6.3, a)', 'force pass (best of 5 x 20): ', 1e3*best_full, ' ms; ', &
        1e9*best_full/npair_list, ' ns per pair within rc + skin'
    print '(a, f7.3, a, f7.3, a, f6.3, a)', '  staging and write-back alone: ', 1e3*best_skip, ' ms; pair loop (difference): ', &
        1e3*(best_full - best_skip), ' ms, ', 1e9*(best_full - best_skip)/(16*real(nlisted, dp)), ' ns per computed pair'
    print '(a, f7.3, a)', '  per listed cluster pair: staging and write-back ', 1e9*best_skip/nlisted, ' ns'
    print '(a, es9.2, a)', 'max |F - F_double| / F_rms: ', err/frms, ' (double reference, minimum image, all pairs)'
    print '(a, f7.3, a, f6.3, a, f6.3, a, es9.2)', 'replicated j layout, j forces in singles: ', 1e3*best_rep(1), ' ms; ', &
        1e9*best_rep(1)/npair_list, ' ns per pair within rc + skin; ', 1e9*best_rep(1)/nlisted, &
        ' ns per cluster pair; max |F - F_double| / F_rms ', err_rep(1)/frms
    print '(a, f7.3, a, f6.3, a, f6.3, a, es9.2)', 'replicated j layout, j forces in doubles: ', 1e3*best_rep(2), ' ms; ', &
        1e9*best_rep(2)/npair_list, ' ns per pair within rc + skin; ', 1e9*best_rep(2)/nlisted, &
        ' ns per cluster pair; max |F - F_double| / F_rms ', err_rep(2)/frms
    print '(a, f7.3, a, f6.3, a, f6.3, a, es9.2)', 'replicated, hi/lo separations, j forces in singles: ', 1e3*best_rep(3), &
        ' ms; ', 1e9*best_rep(3)/npair_list, ' ns per pair within rc + skin; ', 1e9*best_rep(3)/nlisted, &
        ' ns per cluster pair; max |F - F_double| / F_rms ', err_rep(3)/frms

contains

    !> Wall-clock seconds (the basis of Terrace's run-log phases, which the script sets beside these)
    real(dp) function wall()
        integer(int64) :: count, rate
        call system_clock(count, rate)
        wall = real(count, dp)/real(rate, dp)
    end function wall

    !> Positions from a Terrace final-state file (&output final_atoms_file: '#' lines, then
    !> `type x y z vx vy vz` per atom, wrapped into the box) of the same 32,000-atom scene
    subroutine read_atoms(path, x)
        character(len=*), intent(in) :: path
        real(dp), intent(out) :: x(:, :)
        character(len=512) :: line
        integer :: u, ios, n, t
        open (newunit=u, file=path, status='old', action='read', iostat=ios)
        if (ios /= 0) then
            write (error_unit, '(a)') 'cluster_pair_probe: cannot open '//path
            stop 2
        end if
        n = 0
        do
            read (u, '(a)', iostat=ios) line
            if (ios /= 0) exit
            if (line(1:1) == '#' .or. len_trim(line) == 0) cycle
            if (n == natoms) then
                n = n + 1
                exit
            end if
            n = n + 1
            read (line, *) t, x(:, n)
        end do
        close (u)
        if (n /= natoms .or. any(x < 0) .or. any(x >= L)) then
            write (error_unit, '(a, i0, a)') 'cluster_pair_probe: '//path//' must hold ', natoms, &
                ' atoms wrapped into the box of the LJ bench scene'
            stop 2
        end if
    end subroutine read_atoms

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
    subroutine reference(x, f, nrc, nlist, fmix, edge)
        real(dp), intent(in) :: x(:, :)
        real(dp), intent(out) :: f(:, :), fmix(:, :)
        logical, intent(out) :: edge(:)
        integer, intent(out) :: nrc, nlist
        integer :: i, j
        real(dp) :: d(3), r2, r6, fp
        real(sp) :: e(3), s2, s6, sp_fp
        f = 0; fmix = 0; nrc = 0; nlist = 0; edge = .false.
        do i = 1, natoms
            do j = i + 1, natoms
                d = x(:, i) - x(:, j); d = d - L*anint(d/L)
                r2 = d(1)*d(1) + d(2)*d(2) + d(3)*d(3)
                if (r2 < 2.8_dp**2) nlist = nlist + 1
                ! within 1e-6 sigma of the cutoff: single and double precision may decide the pair
                ! differently, and the truncated force jumps there by |F(rc)| = 0.039
                if (abs(sqrt(r2) - rc) < 1.0e-6_dp) then
                    edge(i) = .true.; edge(j) = .true.
                end if
                if (r2 < rc*rc) then
                    nrc = nrc + 1
                    r6 = 1/(r2*r2*r2)
                    fp = r6*(48*r6 - 24)/r2
                    f(:, i) = f(:, i) + fp*d; f(:, j) = f(:, j) - fp*d
                    ! Terrace's mixed kernel: the double separation rounded to single, the pair
                    ! terms in single, the sums in double
                    e = real(d, sp)
                    s2 = e(1)*e(1) + e(2)*e(2) + e(3)*e(3)
                    s6 = 1/(s2*s2*s2); sp_fp = s6*(48*s6 - 24)/s2
                    fmix(:, i) = fmix(:, i) + real(sp_fp*e, dp); fmix(:, j) = fmix(:, j) - real(sp_fp*e, dp)
                end if
            end do
        end do
    end subroutine reference

    !> Clusters and the half list of cluster pairs whose bounding boxes lie within radius (with
    !> atom_check: and one of whose 16 atom pairs does, formed in singles as the passes form them)
    subroutine build(x, radius, ncl, xr, member, centre, half, cfirst, clist, offs, nlisted)
        real(dp), intent(in) :: x(:, :), radius
        integer, intent(out) :: ncl, nlisted
        real(sp), allocatable, intent(out) :: xr(:, :, :), offs(:, :)
        integer, allocatable, intent(out) :: member(:, :), cfirst(:), clist(:)
        real(dp), allocatable, intent(out) :: centre(:, :), half(:, :)
        integer :: ncx, c, i, k, m, kk, ci, cj, dx, dy, cx, cy, p
        integer, allocatable :: count(:), start(:), idx(:), col(:), c0(:)
        real(dp) :: w, d(3), lo(3), hi(3), sxy(2), zz
        real(dp), allocatable :: cc(:, :), hc(:, :)
        real(sp) :: o(3), q(16), xi16(16, 3)
        real(sp), allocatable :: xq(:, :, :)
        integer :: j0, j1, lane, wz, mid, t, ptr(13), near, ncand, cand(100), keep(100)
        real(sp) :: co(3, 100)
        real(sp) :: r2list
        integer, parameter :: sten(2, 13) = reshape([0, 0, 1, 0, 2, 0, -2, 1, -1, 1, 0, 1, 1, 1, 2, 1, &
                                                      -2, 2, -1, 2, 0, 2, 1, 2, 2, 2], [2, 13])
        real(dp) :: za, zb
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
                ! the centre on a grid of 2^-10 sigma: the offset between two centres is then
                ! exact in single precision (a separation rounds only the relative positions)
                centre(:, ci) = anint(0.5_dp*(lo + hi)*1024)/1024
                half(:, ci) = max(hi - centre(:, ci), centre(:, ci) - lo)
                do k = 1, 4
                    xr(k, :, ci) = 300          ! dummies: beyond the cutoff from every atom
                    if (member(k, ci) > 0) xr(k, :, ci) = real(x(:, member(k, ci)) - centre(:, ci), sp)
                end do
            end do
        end do
        allocate (cfirst(ncl + 1), clist(ncl*100 + 1), offs(4, ncl*100 + 1))
        allocate (cc(ncl, 3), hc(ncl, 3), xq(16, 3, ncl))
        cc = transpose(centre); hc = transpose(half)
        do ci = 1, ncl
            do lane = 1, 16
                xq(lane, :, ci) = xr(mod(lane - 1, 4) + 1, :, ci)
            end do
        end do
        r2list = real(radius*radius, sp)
        nlisted = 0
        do c = 1, ncx*ncx
            cx = mod(c - 1, ncx); cy = (c - 1)/ncx
            ! the half stencil: this column (cj > ci) and the 12 columns ahead of it in y, then x
            do t = 1, 13
                m = 1 + modulo(cx + sten(1, t), ncx) + ncx*modulo(cy + sten(2, t), ncx)
                ptr(t) = c0(m)
            end do
            do ci = c0(c), c0(c + 1) - 1
                cfirst(ci) = nlisted + 1
                ncand = 0
                do lane = 1, 16
                    xi16(lane, :) = xr((lane - 1)/4 + 1, :, ci)
                end do
                do t = 1, 13
                    dx = sten(1, t); dy = sten(2, t)
                    m = 1 + modulo(cx + dx, ncx) + ncx*modulo(cy + dy, ncx)
                    ! the column's image shift in x and y is the same for all its clusters
                    sxy(1) = -L*((cx + dx - modulo(cx + dx, ncx))/ncx)
                    sxy(2) = -L*((cy + dy - modulo(cy + dy, ncx))/ncx)
                    ! the column's clusters are z-sorted (their lowest and highest z both ascend):
                    ! only those overlapping ci's z extent widened by the radius are candidates.
                    ! In the box's own image the first of them only moves up as ci does (ptr);
                    ! the images above and below (ci near the top or bottom) by bisection.
                    za = cc(ci, 3) - hc(ci, 3) - radius
                    do while (ptr(t) < c0(m + 1) - 1)
                        if (cc(ptr(t), 3) + hc(ptr(t), 3) > za) exit
                        ptr(t) = ptr(t) + 1
                    end do
                    do wz = -1, 1
                        za = cc(ci, 3) - hc(ci, 3) - radius + wz*L
                        zb = cc(ci, 3) + hc(ci, 3) + radius + wz*L
                        if (zb < 0 .or. za > L) cycle
                        j0 = ptr(t)
                        if (wz /= 0) then
                            j0 = c0(m); j1 = c0(m + 1) - 1
                            do while (j0 < j1)                   ! first cluster whose top is above za
                                mid = (j0 + j1)/2
                                if (cc(mid, 3) + hc(mid, 3) > za) then
                                    j1 = mid
                                else
                                    j0 = mid + 1
                                end if
                            end do
                        end if
                        do cj = j0, c0(m + 1) - 1
                            if (cc(cj, 3) - hc(cj, 3) >= zb) exit
                            d(1) = max(abs(cc(cj, 1) - sxy(1) - cc(ci, 1)) - hc(ci, 1) - hc(cj, 1), 0.0_dp)
                            d(2) = max(abs(cc(cj, 2) - sxy(2) - cc(ci, 2)) - hc(ci, 2) - hc(cj, 2), 0.0_dp)
                            zz = cc(cj, 3) - cc(ci, 3) - wz*L
                            d(3) = max(abs(zz) - hc(ci, 3) - hc(cj, 3), 0.0_dp)
                            ! branch-free: written in the next slot, kept by advancing past it
                            if (ncand == size(cand)) error stop 'cluster_pair_probe: over 100 clusters in a list'
                            cand(ncand + 1) = cj
                            co(1, ncand + 1) = real(cc(cj, 1) - sxy(1) - cc(ci, 1), sp)
                            co(2, ncand + 1) = real(cc(cj, 2) - sxy(2) - cc(ci, 2), sp)
                            co(3, ncand + 1) = real(zz, sp)
                            ncand = ncand + merge(1, 0, d(1)*d(1) + d(2)*d(2) + d(3)*d(3) < radius*radius &
                                                  .and. (t > 1 .or. cj > ci))
                        end do
                    end do
                end do
                ! the candidates' verdicts (with atom_check: any of the 16 pairs within radius, in
                ! singles as the passes form them; counted, not minval: GCC vectorises an integer
                ! sum, not a minval), independent of one another; then the branch-free compaction
                do k = 1, ncand
                    cj = cand(k); o = co(:, k)
                    near = 1
                    if (atom_check) then
                        near = 0
                        do lane = 1, 16
                            q(lane) = ((xi16(lane, 1) - o(1)) - xq(lane, 1, cj))**2 &
                                      + ((xi16(lane, 2) - o(2)) - xq(lane, 2, cj))**2 &
                                      + ((xi16(lane, 3) - o(3)) - xq(lane, 3, cj))**2
                            near = near + merge(1, 0, q(lane) < r2list)
                        end do
                    end if
                    keep(k) = min(near, 1)
                end do
                do k = 1, ncand
                    clist(nlisted + 1) = cand(k)
                    offs(1:3, nlisted + 1) = co(:, k); offs(4, nlisted + 1) = 0
                    nlisted = nlisted + keep(k)
                end do
            end do
        end do
        cfirst(ncl + 1) = nlisted + 1
    end subroutine build

    !> The listed cluster pairs of which one atom pair lies within rin (separations formed in singles
    !> as the passes form them, 16 lanes per cluster pair over replicated positions)
    subroutine prune(ncl, xr, cfirst, clist, offs, rin, cfirst_in, clist_in, offs_in, nkept)
        integer, intent(in) :: ncl, cfirst(ncl + 1), clist(:)
        real(sp), intent(in) :: xr(4, 3, ncl), offs(:, :)
        real(dp), intent(in) :: rin
        integer, allocatable, intent(inout) :: cfirst_in(:), clist_in(:)
        real(sp), allocatable, intent(inout) :: offs_in(:, :)
        integer, intent(out) :: nkept
        real(sp), allocatable, save :: xq(:, :, :)
        real(sp) :: xi16(16, 3), o(3), q, r2in
        integer :: ci, cj, p, lane, near, keep(100)
        if (.not. allocated(cfirst_in)) allocate (cfirst_in(ncl + 1), clist_in(size(clist)), offs_in(4, size(clist)))
        if (allocated(xq)) then
            if (size(xq, 3) /= ncl) deallocate (xq)
        end if
        if (.not. allocated(xq)) allocate (xq(16, 3, ncl))
        do ci = 1, ncl                  ! (every step in an engine: the force pass forms the same replicas)
            do lane = 1, 16
                xq(lane, :, ci) = xr(mod(lane - 1, 4) + 1, :, ci)
            end do
        end do
        r2in = real(rin*rin, sp)
        nkept = 0
        if (maxval(cfirst(2:ncl + 1) - cfirst(1:ncl)) > size(keep)) error stop 'cluster_pair_probe: over 100 clusters in a list'
        do ci = 1, ncl
            cfirst_in(ci) = nkept + 1
            do lane = 1, 16
                xi16(lane, :) = xr((lane - 1)/4 + 1, :, ci)
            end do
            ! first the verdicts of all ci's pairs (independent of one another, so they overlap in
            ! the pipeline), then the compaction (branch-free: each pair written in the next slot,
            ! kept by advancing past it)
            do p = cfirst(ci), cfirst(ci + 1) - 1
                cj = clist(p); o = offs(1:3, p)
                near = 0
                do lane = 1, 16
                    q = ((xi16(lane, 1) - o(1)) - xq(lane, 1, cj))**2 + ((xi16(lane, 2) - o(2)) - xq(lane, 2, cj))**2 &
                        + ((xi16(lane, 3) - o(3)) - xq(lane, 3, cj))**2
                    near = near + merge(1, 0, q < r2in)
                end do
                keep(p - cfirst(ci) + 1) = min(near, 1)
            end do
            do p = cfirst(ci), cfirst(ci + 1) - 1
                clist_in(nkept + 1) = clist(p); offs_in(:, nkept + 1) = offs(:, p)
                nkept = nkept + keep(p - cfirst(ci) + 1)
            end do
        end do
        cfirst_in(ncl + 1) = nkept + 1
    end subroutine prune

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
        integer :: ci, cj, p, n, m, k, kb, l, ii
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
            call within_cluster(ci, xr, xr, .false., f4)
        end do
    end subroutine force_pass

    !> The force pass without staging: every cluster's positions are kept replicated, lane l of the
    !> 16 holding atom mod(l - 1, 4) + 1 (j0 j1 j2 j3 j0 ...), and cluster ci's atoms spread as
    !> (i0 i0 i0 i0 i1 ...), so one listed cluster pair is one 16-lane loop over contiguous
    !> records: its 16 pairs, i forces summed in 16 lanes, j forces added to the j cluster's
    !> replicated force record (16 lanes per component, reduced over the four replicas at the end).
    !> The replicated positions are formed at the start of the pass and the forces reduced at its end
    !> (both timed: an engine would do them every step). j forces in singles.
    subroutine force_pass_rep_s(ncl, xr, cfirst, clist, offs, f4, xrep, frep)
        integer, intent(in) :: ncl, cfirst(ncl + 1), clist(*)
        real(sp), intent(in) :: xr(4, 3, ncl), offs(4, *)
        real(dp), intent(out) :: f4(4, 3, ncl)
        real(sp), intent(inout) :: xrep(16, 3, ncl), frep(16, 3, ncl)
        real(sp) :: xi(16), yi(16), zi(16), ax(16), ay(16), az(16)
        real(sp) :: dx, dy, dz, r2, r2i, r6, fp, cut, ox, oy, oz
        integer :: ci, cj, p, l, ii
        cut = real(rc*rc, sp)
        call replicate(ncl, xr, xrep)
        frep = 0
        f4 = 0
        do ci = 1, ncl
            do l = 1, 16
                xi(l) = xr((l - 1)/4 + 1, 1, ci); yi(l) = xr((l - 1)/4 + 1, 2, ci); zi(l) = xr((l - 1)/4 + 1, 3, ci)
            end do
            ax = 0; ay = 0; az = 0
            do p = cfirst(ci), cfirst(ci + 1) - 1
                cj = clist(p); ox = offs(1, p); oy = offs(2, p); oz = offs(3, p)
                do l = 1, 16
                    dx = (xi(l) - ox) - xrep(l, 1, cj); dy = (yi(l) - oy) - xrep(l, 2, cj); dz = (zi(l) - oz) - xrep(l, 3, cj)
                    r2 = dx*dx + dy*dy + dz*dz
                    r2i = (0.5_sp + sign(0.5_sp, cut - r2))/r2
                    r6 = r2i*r2i*r2i; fp = r6*(48*r6 - 24)*r2i
                    ax(l) = ax(l) + fp*dx; ay(l) = ay(l) + fp*dy; az(l) = az(l) + fp*dz
                    frep(l, 1, cj) = frep(l, 1, cj) - fp*dx
                    frep(l, 2, cj) = frep(l, 2, cj) - fp*dy
                    frep(l, 3, cj) = frep(l, 3, cj) - fp*dz
                end do
            end do
            do ii = 1, 4
                f4(ii, :, ci) = f4(ii, :, ci) + [sum(real(ax(4*ii - 3:4*ii), dp)), sum(real(ay(4*ii - 3:4*ii), dp)), &
                                                 sum(real(az(4*ii - 3:4*ii), dp))]
            end do
            call within_cluster(ci, xr, xr, .false., f4)
        end do
        call add_replicas(ncl, frep, f4)
    end subroutine force_pass_rep_s

    !> force_pass_rep_s with each relative position carried as two singles, hi (xr) + lo (xrl, what
    !> the single loses), as the mixed kernel carries its positions: a separation is
    !> ((hi_i - off) - hi_j) + (lo_i - lo_j), the centres' offset exact on their 2^-10 grid
    subroutine force_pass_rep_hl(ncl, xr, xrl, cfirst, clist, offs, f4, xrep, xrepl, frep)
        integer, intent(in) :: ncl, cfirst(ncl + 1), clist(*)
        real(sp), intent(in) :: xr(4, 3, ncl), xrl(4, 3, ncl), offs(4, *)
        real(dp), intent(out) :: f4(4, 3, ncl)
        real(sp), intent(inout) :: xrep(16, 3, ncl), xrepl(16, 3, ncl), frep(16, 3, ncl)
        real(sp) :: xi(16), yi(16), zi(16), xil(16), yil(16), zil(16), ax(16), ay(16), az(16)
        real(sp) :: dx, dy, dz, r2, r2i, r6, fp, cut, ox, oy, oz
        integer :: ci, cj, p, l, ii
        cut = real(rc*rc, sp)
        call replicate(ncl, xr, xrep); call replicate(ncl, xrl, xrepl)
        frep = 0
        f4 = 0
        do ci = 1, ncl
            do l = 1, 16
                xi(l) = xr((l - 1)/4 + 1, 1, ci); yi(l) = xr((l - 1)/4 + 1, 2, ci); zi(l) = xr((l - 1)/4 + 1, 3, ci)
                xil(l) = xrl((l - 1)/4 + 1, 1, ci); yil(l) = xrl((l - 1)/4 + 1, 2, ci); zil(l) = xrl((l - 1)/4 + 1, 3, ci)
            end do
            ax = 0; ay = 0; az = 0
            do p = cfirst(ci), cfirst(ci + 1) - 1
                cj = clist(p); ox = offs(1, p); oy = offs(2, p); oz = offs(3, p)
                do l = 1, 16
                    dx = ((xi(l) - ox) - xrep(l, 1, cj)) + (xil(l) - xrepl(l, 1, cj))
                    dy = ((yi(l) - oy) - xrep(l, 2, cj)) + (yil(l) - xrepl(l, 2, cj))
                    dz = ((zi(l) - oz) - xrep(l, 3, cj)) + (zil(l) - xrepl(l, 3, cj))
                    r2 = dx*dx + dy*dy + dz*dz
                    r2i = (0.5_sp + sign(0.5_sp, cut - r2))/r2
                    r6 = r2i*r2i*r2i; fp = r6*(48*r6 - 24)*r2i
                    ax(l) = ax(l) + fp*dx; ay(l) = ay(l) + fp*dy; az(l) = az(l) + fp*dz
                    frep(l, 1, cj) = frep(l, 1, cj) - fp*dx
                    frep(l, 2, cj) = frep(l, 2, cj) - fp*dy
                    frep(l, 3, cj) = frep(l, 3, cj) - fp*dz
                end do
            end do
            do ii = 1, 4
                f4(ii, :, ci) = f4(ii, :, ci) + [sum(real(ax(4*ii - 3:4*ii), dp)), sum(real(ay(4*ii - 3:4*ii), dp)), &
                                                 sum(real(az(4*ii - 3:4*ii), dp))]
            end do
            call within_cluster(ci, xr, xrl, .true., f4)
        end do
        call add_replicas(ncl, frep, f4)
    end subroutine force_pass_rep_hl

    !> force_pass_rep_s with the j forces converted to double and summed in doubles
    subroutine force_pass_rep_d(ncl, xr, cfirst, clist, offs, f4, xrep, frep)
        integer, intent(in) :: ncl, cfirst(ncl + 1), clist(*)
        real(sp), intent(in) :: xr(4, 3, ncl), offs(4, *)
        real(dp), intent(out) :: f4(4, 3, ncl)
        real(sp), intent(inout) :: xrep(16, 3, ncl)
        real(dp), intent(inout) :: frep(16, 3, ncl)
        real(sp) :: xi(16), yi(16), zi(16), ax(16), ay(16), az(16)
        real(sp) :: dx, dy, dz, r2, r2i, r6, fp, cut, ox, oy, oz
        integer :: ci, cj, p, l, ii, jj, c
        cut = real(rc*rc, sp)
        call replicate(ncl, xr, xrep)
        frep = 0
        f4 = 0
        do ci = 1, ncl
            do l = 1, 16
                xi(l) = xr((l - 1)/4 + 1, 1, ci); yi(l) = xr((l - 1)/4 + 1, 2, ci); zi(l) = xr((l - 1)/4 + 1, 3, ci)
            end do
            ax = 0; ay = 0; az = 0
            do p = cfirst(ci), cfirst(ci + 1) - 1
                cj = clist(p); ox = offs(1, p); oy = offs(2, p); oz = offs(3, p)
                do l = 1, 16
                    dx = (xi(l) - ox) - xrep(l, 1, cj); dy = (yi(l) - oy) - xrep(l, 2, cj); dz = (zi(l) - oz) - xrep(l, 3, cj)
                    r2 = dx*dx + dy*dy + dz*dz
                    r2i = (0.5_sp + sign(0.5_sp, cut - r2))/r2
                    r6 = r2i*r2i*r2i; fp = r6*(48*r6 - 24)*r2i
                    ax(l) = ax(l) + fp*dx; ay(l) = ay(l) + fp*dy; az(l) = az(l) + fp*dz
                    frep(l, 1, cj) = frep(l, 1, cj) - real(fp*dx, dp)
                    frep(l, 2, cj) = frep(l, 2, cj) - real(fp*dy, dp)
                    frep(l, 3, cj) = frep(l, 3, cj) - real(fp*dz, dp)
                end do
            end do
            do ii = 1, 4
                f4(ii, :, ci) = f4(ii, :, ci) + [sum(real(ax(4*ii - 3:4*ii), dp)), sum(real(ay(4*ii - 3:4*ii), dp)), &
                                                 sum(real(az(4*ii - 3:4*ii), dp))]
            end do
            call within_cluster(ci, xr, xr, .false., f4)
        end do
        do ci = 1, ncl
            do c = 1, 3
                do jj = 1, 4
                    f4(jj, c, ci) = f4(jj, c, ci) + frep(jj, c, ci) + frep(jj + 4, c, ci) + frep(jj + 8, c, ci) &
                                    + frep(jj + 12, c, ci)
                end do
            end do
        end do
    end subroutine force_pass_rep_d

    !> The pairs within cluster ci (scalar; separations from hi + lo when hilo), added to f4
    subroutine within_cluster(ci, xr, xrl, hilo, f4)
        integer, intent(in) :: ci
        real(sp), intent(in) :: xr(4, 3, *), xrl(4, 3, *)
        logical, intent(in) :: hilo
        real(dp), intent(inout) :: f4(4, 3, *)
        real(sp) :: dx, dy, dz, r2, r6, fp, cut
        integer :: ii, jj
        cut = real(rc*rc, sp)
        do ii = 1, 3
            do jj = ii + 1, 4
                dx = xr(ii, 1, ci) - xr(jj, 1, ci); dy = xr(ii, 2, ci) - xr(jj, 2, ci); dz = xr(ii, 3, ci) - xr(jj, 3, ci)
                if (hilo) then
                    dx = dx + (xrl(ii, 1, ci) - xrl(jj, 1, ci)); dy = dy + (xrl(ii, 2, ci) - xrl(jj, 2, ci))
                    dz = dz + (xrl(ii, 3, ci) - xrl(jj, 3, ci))
                end if
                r2 = dx*dx + dy*dy + dz*dz
                if (r2 < cut) then
                    r6 = 1/(r2*r2*r2); fp = r6*(48*r6 - 24)/r2
                    f4(ii, :, ci) = f4(ii, :, ci) + fp*[dx, dy, dz]
                    f4(jj, :, ci) = f4(jj, :, ci) - fp*[dx, dy, dz]
                end if
            end do
        end do
    end subroutine within_cluster

    !> The j side: lane l of 16 holds atom mod(l - 1, 4) + 1 of each cluster
    pure subroutine replicate(ncl, xr, xrep)
        integer, intent(in) :: ncl
        real(sp), intent(in) :: xr(4, 3, ncl)
        real(sp), intent(out) :: xrep(16, 3, ncl)
        integer :: ci, c, l
        do ci = 1, ncl
            do c = 1, 3
                do l = 1, 16
                    xrep(l, c, ci) = xr(mod(l - 1, 4) + 1, c, ci)
                end do
            end do
        end do
    end subroutine replicate

    !> The j forces' four replicas (lanes jj, jj + 4, jj + 8, jj + 12), summed in double into f4
    subroutine add_replicas(ncl, frep, f4)
        integer, intent(in) :: ncl
        real(sp), intent(in) :: frep(16, 3, ncl)
        real(dp), intent(inout) :: f4(4, 3, ncl)
        integer :: ci, c, jj
        do ci = 1, ncl
            do c = 1, 3
                do jj = 1, 4
                    f4(jj, c, ci) = f4(jj, c, ci) + real(frep(jj, c, ci), dp) + real(frep(jj + 4, c, ci), dp) &
                                    + real(frep(jj + 8, c, ci), dp) + real(frep(jj + 12, c, ci), dp)
                end do
            end do
        end do
    end subroutine add_replicas

end program cluster_pair_probe
