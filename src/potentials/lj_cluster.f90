!> The mixed-precision Lennard-Jones kernel over a cluster-pair list (terrace_cluster_list), one
!> atom type, style 'lj' (shifted or not), Newton's third law across ranks as the atom list.
!>
!> Per pass: every cluster's positions relative to its centre, rounded to single, are written
!> replicated in 16 lanes (lane l holds slot mod(l - 1, 4) + 1: j0 j1 j2 j3 j0 ...; empty slots
!> at far_slot). For each owned cluster ci, its slots spread over the lanes (i0 i0 i0 i0 i1 ...;
!> empty ones at -far_slot), and each listed pair is one 16-lane loop over two contiguous records:
!> separation (x_i - offset) - x_j (the centres' offset is exact in single), the pair's mask row
!> added to r^2, single-precision pair terms (as the atom-pair mixed kernel), i forces summed in
!> 16 lanes, j forces added to cj's replicated force record. At the end of ci its four i sums are
!> added to the atoms' double forces, and at the end of the pass every cluster's four j replicas
!> (ghosts too: their forces go back to their owners by the halo's reverse sum). Energy and virial
!> (when wanted) are summed in single per owned cluster, then in double. With AVX-512, or AVX2 and
!> FMA, the pairs of each owned cluster run in C (lj_cluster_simd.c: the same operations in one
!> 512-bit register, or two 256-bit ones).
module terrace_lj_cluster
    use, intrinsic :: iso_fortran_env, only: sp => real32
    use, intrinsic :: iso_c_binding, only: c_int, c_float, c_double
    use terrace_kinds, only: dp
    use terrace_cluster_list, only: cluster_list_t, far_slot
    implicit none
    private

    public :: cluster_forces

    interface
        !> src/potentials/lj_cluster_simd.c: cluster_pairs with AVX-512 or AVX2 (0: not in this build)
        integer(c_int) function c_cluster_pairs(ci, nmem, prange, cjs, mask, offs, masks, xrep, frep, coeffs, &
                                                far_i, want_energy, fi, ew) bind(C, name='terrace_lj_cluster_pairs')
            import :: c_int, c_float, c_double
            integer(c_int), value :: ci, nmem, want_energy
            real(c_float), value :: far_i
            integer(c_int), intent(in) :: prange(3), cjs(*), mask(*)
            real(c_float), intent(in) :: offs(3, *), masks(16, *), xrep(16, 3, *), coeffs(6)
            real(c_float), intent(inout) :: frep(16, 3, *)
            real(c_double), intent(out) :: fi(4, 3), ew(2)
        end function c_cluster_pairs
    end interface

contains

    !> Forces added to f (owned and ghost atoms), and with want_energy the energy and virial
    !> W = sum r.F of the listed pairs. coeffs: the pair's (lj1, lj2, lj3, lj4, cutsq, offset) in
    !> single precision. xrep: the replicated positions (cl%replicate_positions, formed by the
    !> caller); frep: scratch of (16, 3, ncl) or more, zero on entry and zero again on return
    !> (allocate it zeroed).
    subroutine cluster_forces(cl, nall, f, want_energy, coeffs, xrep, frep, energy, virial)
        type(cluster_list_t), intent(in) :: cl
        integer, intent(in) :: nall           !< atoms held (owned and ghost): all are in clusters
        real(dp), intent(inout) :: f(:, :)
        logical, intent(in) :: want_energy
        real(sp), intent(in) :: coeffs(6)
        real(sp), intent(in), contiguous :: xrep(:, :, :)
        real(sp), intent(inout), contiguous :: frep(:, :, :)
        real(dp), intent(out) :: energy, virial
        integer :: ci, ii, a, prange(3)
        real(dp) :: net(3), fi(4, 3), ew(2)
        net = 0
        energy = 0; virial = 0
        do ci = 1, cl%nowned
            prange = [cl%pairs%first(ci), cl%pairs%masked_first(ci), cl%pairs%first(ci + 1) - 1]
            if (c_cluster_pairs(ci, cl%nmem(ci), prange, cl%pairs%cj, cl%pairs%mask, cl%pairs%offset, cl%masks, xrep, &
                                frep, coeffs, -far_slot, merge(1, 0, want_energy), fi, ew) == 0) &
                call cluster_pairs(ci, cl%nmem(ci), prange, cl%pairs%cj, cl%pairs%mask, cl%pairs%offset, cl%masks, &
                                   xrep, frep, coeffs, want_energy, fi, ew)
            energy = energy + ew(1); virial = virial + ew(2)
            do ii = 1, cl%nmem(ci)
                a = cl%member(ii, ci)
                f(:, a) = f(:, a) + fi(ii, :)
                net = net + fi(ii, :)
            end do
        end do
        call add_replicas(cl, frep, f, net)
        ! Newton's third law: every pair adds one single-precision force to i and its negative to
        ! j, but the single-precision lane sums round differently on the two sides and leave a
        ! small net force (without what follows, the momentum bound of tests/regression/
        ! mixed_precision.sh, 1e-10 in 4000 steps, fails). It is taken off equally from every atom
        ! this rank holds, so that the forces of this rank's pairs sum to zero (to double
        ! round-off), and so do all forces after the reverse sum: momentum is conserved as with the
        ! double kernels.
        if (nall > 0) then
            net = net/nall
            do a = 1, nall
                f(:, a) = f(:, a) - net
            end do
        end if
    end subroutine cluster_forces

    !> The pairs of owned cluster ci (nmem atoms): its slots spread over the lanes (lane l: slot
    !> (l - 1)/4 + 1, empty slots at -far_slot), then its listed pairs prange(1)..prange(3) (from
    !> prange(2) on through their mask rows; cjs, mask, offs: the list's cj, mask, offset), j forces
    !> into frep, and the four i sums in double (fi); with want_energy also each lane's pair energy
    !> and virial, summed: ew = (energy, virial) (else 0). The test of want_energy is outside the
    !> lane loops: each of the two loops is the one vectorised pass. (Explicit arrays, not the
    !> list's components: through them the kernel ran 0.7 % more instructions.)
    subroutine cluster_pairs(ci, nmem, prange, cjs, mask, offs, masks, xrep, frep, coeffs, want_energy, fi, ew)
        integer, intent(in) :: ci, nmem, prange(3), cjs(*), mask(*)
        real(sp), intent(in) :: offs(3, *), masks(16, *), xrep(16, 3, *), coeffs(6)
        real(sp), intent(inout) :: frep(16, 3, *)
        logical, intent(in) :: want_energy
        real(dp), intent(out) :: fi(4, 3), ew(2)
        integer :: p, cj, l
        real(sp) :: xi(16, 3), ax(16, 3), el(16), wl(16), ox, oy, oz, dx, dy, dz, r2, r2i, r6, fp, inside, madd(16)
        real(sp) :: lj1, lj2, lj3, lj4, cutsq, offset
        lj1 = coeffs(1); lj2 = coeffs(2); lj3 = coeffs(3); lj4 = coeffs(4); cutsq = coeffs(5); offset = coeffs(6)
        include 'lj_cluster_spread.inc'
        madd = 0
        ax = 0; el = 0; wl = 0
        do p = prange(1), prange(3)
            cj = cjs(p)
            if (p >= prange(2)) madd = masks(:, mask(p))
            ox = offs(1, p); oy = offs(2, p); oz = offs(3, p)
            if (want_energy) then
                do l = 1, 16
                    include 'lj_cluster_lanes.inc'
                    inside = merge(1.0_sp, 0.0_sp, r2 < cutsq)
                    el(l) = el(l) + r6*(lj3*r6 - lj4) - inside*offset
                    wl(l) = wl(l) + fp*r2
                end do
            else
                do l = 1, 16
                    include 'lj_cluster_lanes.inc'
                end do
            end if
        end do
        include 'lj_cluster_isum.inc'
        ew = 0
        if (want_energy) then
            ew(1) = sum(real(el, dp)); ew(2) = sum(real(wl, dp))
        end if
    end subroutine cluster_pairs

    !> Every cluster's four j replicas (lanes s, s + 4, s + 8, s + 12) added in double to its atoms.
    subroutine add_replicas(cl, frep, f, net)
        type(cluster_list_t), intent(in) :: cl
        real(sp), intent(inout), contiguous :: frep(:, :, :)
        real(dp), intent(inout) :: f(:, :), net(3)
        call add_records(cl%ncl, cl%nmem, cl%member, frep, f, net)
    end subroutine add_replicas

    !> add_replicas over explicit arrays (the four replicas summed as 4-wide double vectors; an
    !> empty slot's sum is exactly zero, so the net force takes all four)
    subroutine add_records(ncl, nmem, member, frep, f, net)
        integer, intent(in) :: ncl, nmem(*), member(4, *)
        real(sp), intent(inout) :: frep(16, 3, *)
        real(dp), intent(inout) :: f(:, :), net(3)
        integer :: c, s, a, d
        real(dp) :: t(4, 3)
        do c = 1, ncl
            do d = 1, 3
                t(:, d) = (real(frep(1:4, d, c), dp) + real(frep(5:8, d, c), dp)) &
                          + (real(frep(9:12, d, c), dp) + real(frep(13:16, d, c), dp))
            end do
            frep(:, :, c) = 0      ! zero again for the next pass (the record is in cache now)
            do s = 1, nmem(c)      ! (slots 1..nmem hold the atoms)
                a = member(s, c)
                f(:, a) = f(:, a) + t(s, :)
            end do
            net = net + sum(t, dim=1)
        end do
    end subroutine add_records

end module terrace_lj_cluster
