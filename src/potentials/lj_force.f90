!> Lennard-Jones force passes (terrace_lj): the half-list kernels for one type, several types and
!> lj/smooth/linear, with or without energy and virial; the mixed-precision half-list kernel; the
!> all-pairs path. The pair terms and their table selection are terrace_lj's header.
submodule (terrace_lj) terrace_lj_force
    implicit none

    !> +Infinity: 1/inf = 0 masks pairs beyond the cutoff without a branch (GCC if-converts a
    !> select of two values, not a division that might trap). Read through a volatile so that GCC
    !> cannot fold 1/inf and turn the select back into a branch around the division.
    real(dp), volatile, save :: infinity = transfer(9218868437227405312_int64, 1.0_dp)
    !> 1 and 0 read through volatiles for the 0/1 factor "inside the cutoff" (GCC would otherwise
    !> split x * merge(1, 0, c) into a branch around x * 0, which it may not if-convert either).
    real(dp), volatile, save :: one = 1, zero = 0

contains

    !> The mixed kernel's arrays: staged positions and force records for nall atoms (grown by half
    !> when they grow), rows for the longest list row rounded up to whole blocks.
    module subroutine reserve_mixed(self, list, nall)
        class(lj_t), intent(inout) :: self
        type(neighbor_list_t), intent(in) :: list
        integer, intent(in) :: nall
        integer :: nb
        nb = (list%max_neighbors/block + 1)*block + 1
        if (allocated(self%xs)) then
            if (size(self%xs, 2) < nall) deallocate (self%xs, self%fd)
        end if
        if (.not. allocated(self%xs)) allocate (self%xs(8, nall + nall/2 + 16), self%fd(4, nall + nall/2 + 16))
        if (allocated(self%rows_sp)) then
            if (size(self%rows_sp, 2) < nb) deallocate (self%rows_sp, self%fp_sp, self%ep_sp, self%wp_sp)
        end if
        if (.not. allocated(self%rows_sp)) allocate (self%rows_sp(4, nb), self%fp_sp(nb), self%ep_sp(nb), self%wp_sp(nb))
    end subroutine reserve_mixed

    !> Work rows, one entry per neighbour of the current atom (the longest row of the list, plus a
    !> margin): separations / pair forces (3), per-pair coefficients (up to 8), pair energies and
    !> virials (2); and the per-atom sums of the nlocal owned atoms (3 columns).
    module subroutine reserve_work(self, list, nlocal)
        class(lj_t), intent(inout) :: self
        type(neighbor_list_t), intent(in) :: list
        integer, intent(in) :: nlocal
        integer :: nb
        nb = list%max_neighbors + 16
        if (allocated(self%work)) then
            if (size(self%work, 1) < nb .or. size(self%work, 2) < 13) deallocate (self%work)
        end if
        if (.not. allocated(self%work)) allocate (self%work(nb, 13))
        ! (allocated for one type too: the kernel takes a type row whether or not it reads it)
        call reserve(self%type_row, 8)
        if (allocated(self%atom_sums)) then
            if (size(self%atom_sums, 1) < nlocal) deallocate (self%atom_sums)
        end if
        if (.not. allocated(self%atom_sums)) allocate (self%atom_sums(max(nlocal + nlocal/4, 1), 3))
    end subroutine reserve_work

    !> The potential interface: the half list, or all pairs when the plan chose no list.
    module subroutine lj_forces(self, atoms, list, halo, want_energy, energy, virial)
        class(lj_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        type(neighbor_list_t), intent(in) :: list
        class(halo_ops_t), intent(inout) :: halo
        logical, intent(in) :: want_energy
        real(dp), intent(out) :: energy, virial
        if (list%all_pairs) then
            call self%compute_all_pairs(atoms, energy, virial)
        else
            call self%compute(atoms, list, want_energy, energy, virial)
        end if
    end subroutine lj_forces

    !> Forces (added to atoms%f for owned and ghost atoms) from the half list; when want_energy,
    !> also the energy and the virial W = sum r.F of the pairs this rank holds. One type in double
    !> precision: the fused AVX-512 kernel of lj_simd.c where the build has AVX-512 (eight pairs
    !> gathered, computed and scattered in registers: Pair 0.85 of `kernel`'s on the LJ bench
    !> scene, doc/performance.md), else `kernel`; the same fused pass for 2 to 8 types (style 'lj',
    !> not smooth), each lane's coefficients permuted from its neighbour type (list%ntype).
    module subroutine lj_compute(self, atoms, list, want_energy, energy, virial)
        class(lj_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        type(neighbor_list_t), intent(in) :: list
        logical, intent(in) :: want_energy
        real(dp), intent(out) :: energy, virial
        integer :: fused
        energy = 0; virial = 0
        if (self%mixed .and. list%want_clusters) then
            associate (ncl => list%clusters%ncl)
                if (allocated(self%xrep)) then
                    if (size(self%xrep, 3) < ncl) deallocate (self%xrep, self%frep)
                end if
                if (.not. allocated(self%xrep)) then
                    allocate (self%xrep(16, 3, ncl + ncl/4 + 1), self%frep(16, 3, ncl + ncl/4 + 1))
                    self%frep = 0      ! (the kernel leaves it zero after each pass)
                end if
            end associate
            if (list%builds /= self%cluster_build) then
                ! the list was built at these positions, and its build formed their replicas (xq)
                self%cluster_build = list%builds
                call cluster_pass(list%clusters%xq)
            else
                call list%clusters%replicate_positions(atoms%x, self%xrep)
                call cluster_pass(self%xrep)
            end if
            return
        end if
        if (self%mixed) then
            call reserve_mixed(self, list, atoms%nlocal + atoms%nghost)
            call kernel_mixed(atoms%nlocal, atoms%nlocal + atoms%nghost, atoms%x, atoms%f, list%first, list%neigh, &
                              want_energy, real(self%lj1(1, 1), sp), real(self%lj2(1, 1), sp), &
                              real(self%lj3(1, 1), sp), real(self%lj4(1, 1), sp), real(self%cutsq(1, 1), sp), &
                              real(self%offset(1, 1), sp), size(self%ep_sp), self%xs, self%fd, &
                              self%rows_sp, self%fp_sp, self%ep_sp, self%wp_sp, energy, virial)
            return
        end if
        call reserve_work(self, list, atoms%nlocal)
        ! the fused pass (lj_simd.c; 0: not in this build, or nine and more types): per-atom energies
        ! into atom_sums, summed as kernel's
        fused = 0
        if (self%ntypes == 1 .and. .not. self%smooth) then
            fused = c_lj_one_type(atoms%nlocal, atoms%x, atoms%f, list%first, list%neigh, self%lj1(1, 1), self%lj2(1, 1), &
                                  self%lj3(1, 1), self%lj4(1, 1), self%cutsq(1, 1), self%offset(1, 1), &
                                  merge(1, 0, want_energy), self%atom_sums(:, 1), virial)
        else if (self%ntypes > 1 .and. list%want_types .and. .not. self%smooth) then
            fused = c_lj_types(atoms%nlocal, atoms%x, atoms%f, list%first, list%neigh, atoms%type, list%ntype, self%ntypes, &
                               self%lj1, self%lj2, self%lj3, self%lj4, self%cutsq, self%offset, merge(1, 0, want_energy), &
                               self%atom_sums(:, 1), virial)
        end if
        if (fused /= 0) then
            if (want_energy) energy = compensated_total(self%atom_sums(:, 1), atoms%nlocal)
            return
        end if
        if (self%ntypes > 1 .and. list%want_types) then
            call kernel(self, atoms%nlocal, atoms%x, atoms%f, atoms%type, list%first, list%neigh, list%ntype, want_energy, &
                        infinity, one, zero, self%work, self%atom_sums(:, 1), energy, virial)
        else
            if (self%ntypes > 1) call gather_neighbour_types(list, atoms%type, atoms%nlocal, self%type_row)
            call kernel(self, atoms%nlocal, atoms%x, atoms%f, atoms%type, list%first, list%neigh, self%type_row, &
                        want_energy, infinity, one, zero, self%work, self%atom_sums(:, 1), energy, virial)
        end if
        if (want_energy) energy = energy + compensated_total(self%atom_sums(:, 1), atoms%nlocal)

    contains

        !> The mixed kernel over the cluster-pair list, with the replicated positions xr.
        subroutine cluster_pass(xr)
            real(sp), intent(in), contiguous :: xr(:, :, :)
            call cluster_forces(list%clusters, atoms%nlocal + atoms%nghost, atoms%f, want_energy, &
                                real(self%lj1(1, 1), sp), real(self%lj2(1, 1), sp), real(self%lj3(1, 1), sp), &
                                real(self%lj4(1, 1), sp), real(self%cutsq(1, 1), sp), real(self%offset(1, 1), sp), &
                                xr, self%frep, energy, virial)
        end subroutine cluster_pass
    end subroutine lj_compute

    !> The half-list kernel. Three passes per atom: the separations to all its neighbours are
    !> gathered into the columns of work (scalar loads, contiguous stores; with several types the
    !> neighbours' types are a row of the list, ntr, filled at its builds); the pair forces (and,
    !> when want_energy, the pair energies and virials) are computed branch-free over the
    !> contiguous rows, padded to a multiple of 8 with far pairs (vectorised, eight lanes, no
    !> scalar remainder; GCC does not emit gathers for this CPU); then they are scattered
    !> (Newton's third law) while the force on i is summed in list order. One type (lj/cut): scalar
    !> coefficients, and the energies and virials summed in eight lanes as they are computed
    !> (one_type_pairs_energy). Two to four types, forces only: each pair's coefficients selected
    !> in the pair loop from i's (pair_forces_two_types, pair_forces_few_types).
    !> Otherwise per-pair coefficient rows, selected per type (select_by_type), and for 'lj' the
    !> energies and virials summed in lanes (pairs_energy_rows); lj/smooth/linear stores them in
    !> rows, summed in list order after the scatter.
    !> Columns of work: separations / pair forces 1-3, lj1, lj2, cutsq, lj3, lj4, offset, pair
    !> energy, pair virial; for lj/smooth/linear also 12, 13: rc and fc (fpair - fc/r and the
    !> energy term (r - rc) fc).
    subroutine kernel(self, nlocal, x, f, type, first, neigh, ntr, want_energy, inf, one_, zero_, work, atom_e, energy, &
                      virial)
        type(lj_t), intent(in) :: self
        integer, intent(in) :: nlocal
        integer, intent(in), contiguous :: type(:), first(:), neigh(:), ntr(:)
        real(dp), intent(in), contiguous :: x(:, :)
        real(dp), intent(in) :: inf, one_, zero_
        real(dp), intent(inout), contiguous :: f(:, :)
        real(dp), intent(inout) :: energy, virial
        logical, intent(in) :: want_energy
        real(dp), intent(inout), contiguous, target :: work(:, :)
        real(dp), intent(inout) :: atom_e(:)
        integer :: i, k, j, k0, nn, ti, ntypes
        real(dp) :: xi, yi, zi, fxi, fyi, fzi, w, ea, wa, far, one, zero, lj1, lj2, lj3, lj4, cutsq, offset
        logical :: one_type, smooth
        real(dp), pointer, contiguous :: fx(:), fy(:), fz(:), c1(:), c2(:), cs(:), c3(:), c4(:), co(:), ep(:), wp(:), &
                                         crc(:), cfc(:)
        fx => work(:, 1); fy => work(:, 2); fz => work(:, 3); c1 => work(:, 4); c2 => work(:, 5); cs => work(:, 6)
        c3 => work(:, 7); c4 => work(:, 8); co => work(:, 9); ep => work(:, 10); wp => work(:, 11)
        crc => work(:, 12); cfc => work(:, 13)
        far = inf; one = one_; zero = zero_
        smooth = self%smooth
        one_type = self%ntypes == 1 .and. .not. smooth
        ntypes = self%ntypes
        lj1 = self%lj1(1, 1); lj2 = self%lj2(1, 1); lj3 = self%lj3(1, 1); lj4 = self%lj4(1, 1)
        cutsq = self%cutsq(1, 1); offset = self%offset(1, 1)
        w = 0
        do i = 1, nlocal
            xi = x(1, i); yi = x(2, i); zi = x(3, i)
            k0 = first(i) - 1
            nn = first(i + 1) - first(i)
            if (one_type) then
                call separations(xi, yi, zi, x, neigh(k0 + 1:k0 + nn), fx, fy, fz)
                if (want_energy) then
                    call one_type_pairs_energy(nn, fx, fy, fz, lj1, lj2, lj3, lj4, cutsq, offset, far, one, zero, ea, wa)
                    atom_e(i) = ea; w = w + wa
                else
                    call one_type_pairs(nn, fx, fy, fz, lj1, lj2, cutsq, far)
                end if
            else
                ti = type(i)
                call separations(xi, yi, zi, x, neigh(k0 + 1:k0 + nn), fx, fy, fz)
                associate (tr => ntr(k0 + 1:))
                if (ntypes == 2 .and. .not. (smooth .or. want_energy)) then
                    ! the common mixture: coefficients selected in the pair loop, no per-pair rows
                    call pair_forces_two_types(nn, fx, fy, fz, tr, self%lj1(:, ti), self%lj2(:, ti), self%cutsq(:, ti), far)
                else if (ntypes == 3 .and. .not. (smooth .or. want_energy)) then
                    call pair_forces_three_types(nn, fx, fy, fz, tr, self%lj1(:, ti), self%lj2(:, ti), self%cutsq(:, ti), &
                                                 far)
                else if (ntypes <= 4 .and. .not. (smooth .or. want_energy)) then
                    call pair_forces_few_types(nn, fx, fy, fz, tr, self%lj1(:, ti), self%lj2(:, ti), self%cutsq(:, ti), &
                                               far)
                else
                    call select_by_type(nn, ntypes, tr, self%lj1(:, ti), self%lj2(:, ti), self%cutsq(:, ti), c1, c2, cs)
                    ! (a third row is filled and not used: ep, written later by the energy pass)
                    if (smooth) call select_by_type(nn, ntypes, tr, self%fc(:, ti), self%rc(:, ti), self%fc(:, ti), &
                                                    cfc, crc, ep)
                    if (want_energy) then
                        call select_by_type(nn, ntypes, tr, self%lj3(:, ti), self%lj4(:, ti), self%offset(:, ti), c3, c4, &
                                            co)
                        if (smooth) then
                            call pair_forces_smooth_energy(nn, fx, fy, fz, c1, c2, cs, c3, c4, co, crc, cfc, far, one, &
                                                           zero, ep, wp)
                        else
                            ! the energies and virials summed in lanes as they are computed
                            call pairs_energy_rows(nn, fx, fy, fz, c1, c2, cs, c3, c4, co, far, one, zero, ea, wa)
                            atom_e(i) = ea; w = w + wa
                        end if
                    else if (smooth) then
                        call pair_forces_smooth(nn, fx, fy, fz, c1, c2, cs, cfc, far)
                    else
                        call pair_forces(nn, fx, fy, fz, c1, c2, cs, far)
                    end if
                end if
                end associate
            end if
            fxi = 0; fyi = 0; fzi = 0
            do k = 1, nn
                j = neigh(k0 + k)
                f(1, j) = f(1, j) - fx(k); f(2, j) = f(2, j) - fy(k); f(3, j) = f(3, j) - fz(k)
                fxi = fxi + fx(k); fyi = fyi + fy(k); fzi = fzi + fz(k)
            end do
            f(1, i) = f(1, i) + fxi; f(2, i) = f(2, i) + fyi; f(3, i) = f(3, i) + fzi
            if (want_energy .and. smooth) then
                ! per-atom sums, totalled by the caller (compensated): with the total formed here,
                ! every force pass, with energy or not, ran 5-8 % slower (Verlet, in.lj scene)
                ea = 0; wa = 0
                do k = 1, nn
                    ea = ea + ep(k); wa = wa + wp(k)
                end do
                atom_e(i) = ea; w = w + wa
            end if
        end do
        virial = virial + w
    end subroutine kernel

    !> The mixed-precision half-list kernel (one type). Each call first stages every position
    !> (owned and ghost) as two singles, hi = x rounded to single and lo = x - hi rounded to single,
    !> in one 8-single record (hi x, y, z, 0, lo x, y, z, 0). A separation is then
    !> (hi_i - hi_j) + (lo_i - lo_j): the first difference is exact or off by half an ulp of the
    !> separation itself, the second carries the bits that single positions lose, so the separation
    !> is the double one to about 1e-7 relative, whatever the atoms' distance from the origin. Per
    !> atom i: the separations to its neighbours are gathered as 4-single rows (two 16-byte loads per
    !> neighbour); the pair terms are computed in single precision over blocks of 16 pairs (one
    !> AVX-512 vector; the rows are padded with separations beyond the cutoff); the pair forces are
    !> converted to double and subtracted from j's 4-double force record (one 32-byte vector) and
    !> summed into i's, and the pair energies and virials are summed in double. The records are added
    !> to f at the end.
    subroutine kernel_mixed(nlocal, nall, x, f, first, neigh, want_energy, lj1, lj2, lj3, lj4, cutsq, offset, nrow, &
                            xs, fd, rows, fp, ep, wp, energy, virial)
        integer, intent(in) :: nlocal, nall, nrow
        integer, intent(in), contiguous :: first(:), neigh(:)
        real(dp), intent(in), contiguous :: x(:, :)
        real(dp), intent(inout), contiguous :: f(:, :)
        logical, intent(in) :: want_energy
        real(sp), intent(in) :: lj1, lj2, lj3, lj4, cutsq, offset
        real(sp), intent(inout) :: xs(8, nall), rows(4, nrow), fp(nrow), ep(nrow), wp(nrow)
        real(dp), intent(inout) :: fd(4, nall)
        real(dp), intent(inout) :: energy, virial
        integer :: i, k, j, k0, nn, nblocks, c
        real(dp) :: e, w, fi(4)
        real(sp) :: hi(4), lo(4), beyond
        beyond = 2*sqrt(cutsq) + 1
        do i = 1, nall
            do c = 1, 3
                xs(c, i) = real(x(c, i), sp)
                xs(4 + c, i) = real(x(c, i) - real(xs(c, i), dp), sp)
            end do
            xs(4, i) = 0; xs(8, i) = 0
            fd(:, i) = 0
        end do
        e = 0; w = 0
        do i = 1, nlocal
            hi = xs(1:4, i); lo = xs(5:8, i)
            k0 = first(i) - 1
            nn = first(i + 1) - first(i)
            !GCC$ novector
            do k = 1, nn
                j = neigh(k0 + k)
                rows(:, k) = (hi - xs(1:4, j)) + (lo - xs(5:8, j))
            end do
            nblocks = (nn + block - 1)/block
            do k = nn + 1, nblocks*block + 1
                rows(1, k) = beyond; rows(2, k) = 0; rows(3, k) = 0; rows(4, k) = 0
            end do
            call pairs_mixed(nblocks*block + 1, rows, want_energy, lj1, lj2, lj3, lj4, cutsq, offset, fp, ep, wp)
            call scatter_mixed(nn, neigh(k0 + 1:k0 + nn), rows, fp, fd, fi)
            fd(:, i) = fd(:, i) + fi
            if (want_energy) then
                do k = 1, nn
                    e = e + real(ep(k), dp); w = w + real(wp(k), dp)
                end do
            end if
        end do
        do i = 1, nall
            f(1, i) = f(1, i) + fd(1, i); f(2, i) = f(2, i) + fd(2, i); f(3, i) = f(3, i) + fd(3, i)
        end do
        energy = energy + e; virial = virial + w
    end subroutine kernel_mixed

    !> The mixed kernel's scatter: pair force k = rows(:, k) fp(k), converted to double, is subtracted
    !> from the force record of neighbour nbrs(k) and summed into fi (one 32-byte vector each).
    pure subroutine scatter_mixed(nn, nbrs, rows, fp, fd, fi)
        integer, intent(in) :: nn, nbrs(nn)
        real(sp), intent(in) :: rows(4, *), fp(*)
        real(dp), intent(inout) :: fd(4, *)
        real(dp), intent(out) :: fi(4)
        integer :: k, j
        real(dp) :: fk(4), acc(4), fj(4)
        acc = 0
        !GCC$ novector
        do k = 1, nn
            j = nbrs(k)
            fk = real(rows(:, k)*fp(k), dp)
            fj = fd(:, j)             ! through a local: GCC then vectorises the update
            fd(:, j) = fj - fk
            acc = acc + fk
        end do
        fi = acc
    end subroutine scatter_mixed

    !> one_type_pairs in single precision over n pairs (16 m + 1: GCC keeps the last pair of these
    !> stride-4 rows for a scalar remainder, so one padding pair more makes the 16-wide loop cover all
    !> the real ones; without it up to 16 pairs per atom ran in the 8-wide and scalar remainders
    !> and the mixed kernel was slower than the double one): the separations in rows
    !> (x, y, z, 0 per pair) are replaced by the pair forces (x, y, z, 0); with want_energy also the
    !> pair energies ep and virials wp. The cutoff is the factor inside = 1/2 + sign(1/2, rc^2 - r^2)
    !> (1 inside, 0 beyond; GCC vectorises these stride-4 rows with sign, not with merge).
    pure subroutine pairs_mixed(n, rows, want_energy, lj1, lj2, lj3, lj4, cutsq, offset, fp, ep, wp)
        integer, intent(in) :: n
        real(sp), intent(in) :: rows(4, n)
        real(sp), intent(out) :: fp(n), ep(n), wp(n)
        logical, intent(in) :: want_energy
        real(sp), intent(in) :: lj1, lj2, lj3, lj4, cutsq, offset
        integer :: k
        real(sp) :: dx, dy, dz, rsq, r2inv, r6inv, fpair, inside
        if (want_energy) then
            do k = 1, n
                dx = rows(1, k); dy = rows(2, k); dz = rows(3, k)
                rsq = dx*dx + dy*dy + dz*dz
                inside = 0.5_sp + sign(0.5_sp, cutsq - rsq)
                r2inv = inside/rsq
                r6inv = r2inv*r2inv*r2inv
                fpair = r6inv*(lj1*r6inv - lj2)*r2inv
                ep(k) = r6inv*(lj3*r6inv - lj4) - offset*inside
                wp(k) = rsq*fpair
                fp(k) = fpair
            end do
        else
            do k = 1, n
                dx = rows(1, k); dy = rows(2, k); dz = rows(3, k)
                rsq = dx*dx + dy*dy + dz*dz
                r2inv = (0.5_sp + sign(0.5_sp, cutsq - rsq))/rsq
                r6inv = r2inv*r2inv*r2inv
                fpair = r6inv*(lj1*r6inv - lj2)*r2inv
                fp(k) = fpair
            end do
        end if
    end subroutine pairs_mixed

    !> One type: pair forces fpair*(dx, dy, dz) in place of the separations, with scalar
    !> coefficients. The rows are padded to a multiple of 8 with far pairs (force exactly 0), so
    !> the loop runs in whole eight-lane blocks: they must have room for nn + 8 entries.
    pure subroutine one_type_pairs(nn, fx, fy, fz, lj1, lj2, cutsq, far)
        integer, intent(in) :: nn
        real(dp), intent(inout) :: fx(*), fy(*), fz(*)
        real(dp), intent(in) :: lj1, lj2, cutsq, far
        integer :: k, l, kk, nnp
        real(dp) :: rsq, r2inv, r6inv, fpair
        call pad_rows(nn, fx, fy, fz, pad_far, nnp)
        do k = 1, nnp, 8
            do l = 1, 8
                kk = k + l - 1
                rsq = fx(kk)*fx(kk) + fy(kk)*fy(kk) + fz(kk)*fz(kk)
                call lj_terms(rsq, cutsq, far, lj1, lj2, r2inv, r6inv, fpair)
                fx(kk) = fx(kk)*fpair; fy(kk) = fy(kk)*fpair; fz(kk) = fz(kk)*fpair
            end do
        end do
    end subroutine one_type_pairs

    !> one_type_pairs plus the atom's pair-energy sum ea and virial sum wa, added into eight lanes
    !> as the pairs are computed (as ray_one_type does: storing per-pair rows and summing them in a
    !> second pass made the energy-stepping force pass dearer per pair than Verlet's). The rows
    !> are padded to a multiple of 8 with far pairs (force, energy and virial exactly 0): the rows
    !> must have room for nn + 8 entries.
    pure subroutine one_type_pairs_energy(nn, fx, fy, fz, lj1, lj2, lj3, lj4, cutsq, offset, far, one, zero, ea, wa)
        integer, intent(in) :: nn
        real(dp), intent(inout) :: fx(*), fy(*), fz(*)
        real(dp), intent(in) :: lj1, lj2, lj3, lj4, cutsq, offset, far, one, zero
        real(dp), intent(out) :: ea, wa
        integer :: k, l, kk, nnp
        real(dp) :: rsq, r2inv, r6inv, fpair, inside, le(8), lw(8)
        real(dp) :: p_lj1, p_lj2, p_lj3, p_lj4, p_cs, p_off   !< the pair's coefficients (lj_force_lanes.inc)
        p_lj1 = lj1; p_lj2 = lj2; p_lj3 = lj3; p_lj4 = lj4; p_cs = cutsq; p_off = offset
        call pad_rows(nn, fx, fy, fz, pad_far, nnp)
        le = 0; lw = 0
        do k = 1, nnp, 8
            do l = 1, 8
                kk = k + l - 1
                include 'lj_force_lanes.inc'
            end do
        end do
        ea = sum(le); wa = sum(lw)
    end subroutine one_type_pairs_energy

    !> pair_forces for two atom types: the coefficients of the pair selected in the loop from atom
    !> i's two (a1, a2, as: its column of the tables) by the neighbour's type tr(k). Eight-lane
    !> blocks over padded rows as one_type_pairs (tr(nn+1 : nn+8) must be readable).
    pure subroutine pair_forces_two_types(nn, fx, fy, fz, tr, a1, a2, as, far)
        integer, intent(in) :: nn
        real(dp), intent(inout) :: fx(*), fy(*), fz(*)
        integer, intent(in) :: tr(*)
        real(dp), intent(in) :: a1(:), a2(:), as(:), far
        integer :: k, l, kk, nnp
        real(dp) :: rsq, r2inv, r6inv, fpair, c1, c2, cs, a11, a12, a21, a22, as1, as2
        a11 = a1(1); a12 = a1(2); a21 = a2(1); a22 = a2(2); as1 = as(1); as2 = as(2)
        call pad_rows(nn, fx, fy, fz, pad_far, nnp)
        do k = 1, nnp, 8
            do l = 1, 8
                kk = k + l - 1
                c1 = merge(a12, a11, tr(kk) == 2); c2 = merge(a22, a21, tr(kk) == 2); cs = merge(as2, as1, tr(kk) == 2)
                rsq = fx(kk)*fx(kk) + fy(kk)*fy(kk) + fz(kk)*fz(kk)
                call lj_terms(rsq, cs, far, c1, c2, r2inv, r6inv, fpair)
                fx(kk) = fx(kk)*fpair; fy(kk) = fy(kk)*fpair; fz(kk) = fz(kk)*fpair
            end do
        end do
    end subroutine pair_forces_two_types

    !> pair_forces for three atom types: pair_forces_two_types with a chain of two selects per
    !> coefficient (type 2, then type 3).
    pure subroutine pair_forces_three_types(nn, fx, fy, fz, tr, a1, a2, as, far)
        integer, intent(in) :: nn
        real(dp), intent(inout) :: fx(*), fy(*), fz(*)
        integer, intent(in) :: tr(*)
        real(dp), intent(in) :: a1(:), a2(:), as(:), far
        integer :: k, l, kk, nnp
        real(dp) :: rsq, r2inv, r6inv, fpair, c1, c2, cs, a11, a12, a13, a21, a22, a23, as1, as2, as3
        logical :: is2, is3
        a11 = a1(1); a12 = a1(2); a13 = a1(3); a21 = a2(1); a22 = a2(2); a23 = a2(3)
        as1 = as(1); as2 = as(2); as3 = as(3)
        call pad_rows(nn, fx, fy, fz, pad_far, nnp)
        do k = 1, nnp, 8
            do l = 1, 8
                kk = k + l - 1
                is2 = tr(kk) == 2; is3 = tr(kk) == 3
                c1 = merge(a13, merge(a12, a11, is2), is3)
                c2 = merge(a23, merge(a22, a21, is2), is3)
                cs = merge(as3, merge(as2, as1, is2), is3)
                rsq = fx(kk)*fx(kk) + fy(kk)*fy(kk) + fz(kk)*fz(kk)
                call lj_terms(rsq, cs, far, c1, c2, r2inv, r6inv, fpair)
                fx(kk) = fx(kk)*fpair; fy(kk) = fy(kk)*fpair; fz(kk) = fz(kk)*fpair
            end do
        end do
    end subroutine pair_forces_three_types

    !> pair_forces for three or four atom types: the coefficients of the pair selected in the loop
    !> from atom i's (a1, a2, as: its column of the tables, padded to four) by the neighbour's type
    !> tr(k), with a two-level select (three per coefficient). For two types the one select of
    !> pair_forces_two_types is faster; for more than four, rows (select_by_type).
    pure subroutine pair_forces_few_types(nn, fx, fy, fz, tr, a1, a2, as, far)
        integer, intent(in) :: nn
        real(dp), intent(inout) :: fx(*), fy(*), fz(*)
        integer, intent(in) :: tr(*)
        real(dp), intent(in) :: a1(:), a2(:), as(:), far
        integer :: k, l, kk, nnp, t
        real(dp) :: rsq, r2inv, r6inv, fpair, c1, c2, cs, p1(4), p2(4), ps(4)
        logical :: odd, high
        p1 = a1(1); p2 = a2(1); ps = as(1)
        p1(1:size(a1)) = a1; p2(1:size(a2)) = a2; ps(1:size(as)) = as
        call pad_rows(nn, fx, fy, fz, pad_far, nnp)
        do k = 1, nnp, 8
            do l = 1, 8
                kk = k + l - 1
                t = tr(kk)
                odd = iand(t, 1) == 1; high = t > 2
                c1 = merge(merge(p1(3), p1(4), odd), merge(p1(1), p1(2), odd), high)
                c2 = merge(merge(p2(3), p2(4), odd), merge(p2(1), p2(2), odd), high)
                cs = merge(merge(ps(3), ps(4), odd), merge(ps(1), ps(2), odd), high)
                rsq = fx(kk)*fx(kk) + fy(kk)*fy(kk) + fz(kk)*fz(kk)
                call lj_terms(rsq, cs, far, c1, c2, r2inv, r6inv, fpair)
                fx(kk) = fx(kk)*fpair; fy(kk) = fy(kk)*fpair; fz(kk) = fz(kk)*fpair
            end do
        end do
    end subroutine pair_forces_few_types

    !> pair_forces with per-pair coefficient rows, plus the atom's pair-energy sum ea and virial sum
    !> wa added into eight lanes as they are computed (one_type_pairs_energy's loop). The rows
    !> (separations and coefficients) are padded to a multiple of 8 with far pairs whose
    !> coefficients are 0: they must have room for nn + 8 entries.
    pure subroutine pairs_energy_rows(nn, fx, fy, fz, c1, c2, cs, c3, c4, co, far, one, zero, ea, wa)
        integer, intent(in) :: nn
        real(dp), intent(inout) :: fx(*), fy(*), fz(*), c1(*), c2(*), cs(*), c3(*), c4(*), co(*)
        real(dp), intent(in) :: far, one, zero
        real(dp), intent(out) :: ea, wa
        integer :: k, l, kk, nnp
        real(dp) :: rsq, r2inv, r6inv, fpair, inside, le(8), lw(8)
        real(dp) :: p_lj1, p_lj2, p_lj3, p_lj4, p_cs, p_off   !< the pair's coefficients (lj_force_lanes.inc)
        call pad_rows(nn, fx, fy, fz, pad_far, nnp)
        call pad_rows(nn, c1, c2, cs, 0.0_dp, nnp)
        call pad_rows(nn, c3, c4, co, 0.0_dp, nnp)
        le = 0; lw = 0
        do k = 1, nnp, 8
            do l = 1, 8
                kk = k + l - 1
                p_cs = cs(kk); p_lj1 = c1(kk); p_lj2 = c2(kk); p_lj3 = c3(kk); p_lj4 = c4(kk); p_off = co(kk)
                include 'lj_force_lanes.inc'
            end do
        end do
        ea = sum(le); wa = sum(lw)
    end subroutine pairs_energy_rows

    !> Pair forces fpair*(dx, dy, dz) in place of the separations, per-pair coefficients.
    pure subroutine pair_forces(nn, fx, fy, fz, c1, c2, cs, far)
        integer, intent(in) :: nn
        real(dp), intent(inout) :: fx(nn), fy(nn), fz(nn)
        real(dp), intent(in) :: c1(nn), c2(nn), cs(nn), far
        integer :: k
        real(dp) :: rsq, r2inv, r6inv, fpair
        do k = 1, nn
            rsq = fx(k)*fx(k) + fy(k)*fy(k) + fz(k)*fz(k)
            call lj_terms(rsq, cs(k), far, c1(k), c2(k), r2inv, r6inv, fpair)
            fx(k) = fx(k)*fpair; fy(k) = fy(k)*fpair; fz(k) = fz(k)*fpair
        end do
    end subroutine pair_forces

    !> lj/smooth/linear pair forces: fpair - fc/r.
    pure subroutine pair_forces_smooth(nn, fx, fy, fz, c1, c2, cs, cfc, far)
        integer, intent(in) :: nn
        real(dp), intent(inout) :: fx(nn), fy(nn), fz(nn)
        real(dp), intent(in) :: c1(nn), c2(nn), cs(nn), cfc(nn), far
        integer :: k
        real(dp) :: rsq, r2inv, r6inv, fpair, r, rinv
        do k = 1, nn
            rsq = fx(k)*fx(k) + fy(k)*fy(k) + fz(k)*fz(k)
            call lj_terms(rsq, cs(k), far, c1(k), c2(k), r2inv, r6inv, fpair)
            r = sqrt(rsq)
            rinv = r*r2inv                       ! 1/r inside the cutoff, 0 beyond
            fpair = fpair - cfc(k)*rinv
            fx(k) = fx(k)*fpair; fy(k) = fy(k)*fpair; fz(k) = fz(k)*fpair
        end do
    end subroutine pair_forces_smooth

    !> pair_forces_smooth plus pair energies (+ (r - rc) fc) and virials.
    pure subroutine pair_forces_smooth_energy(nn, fx, fy, fz, c1, c2, cs, c3, c4, co, crc, cfc, far, one, zero, ep, wp)
        integer, intent(in) :: nn
        real(dp), intent(inout) :: fx(nn), fy(nn), fz(nn)
        real(dp), intent(in) :: c1(nn), c2(nn), cs(nn), c3(nn), c4(nn), co(nn), crc(nn), cfc(nn), far, one, zero
        real(dp), intent(out) :: ep(nn), wp(nn)
        integer :: k
        real(dp) :: rsq, r2inv, r6inv, fpair, inside, r, rinv
        do k = 1, nn
            rsq = fx(k)*fx(k) + fy(k)*fy(k) + fz(k)*fz(k)
            inside = merge(one, zero, rsq < cs(k))
            call lj_terms(rsq, cs(k), far, c1(k), c2(k), r2inv, r6inv, fpair)
            r = sqrt(rsq)
            rinv = r*r2inv                       ! 1/r inside the cutoff, 0 beyond
            fpair = fpair - cfc(k)*rinv
            ep(k) = r6inv*(c3(k)*r6inv - c4(k)) - co(k)*inside + (r - crc(k))*cfc(k)*inside
            wp(k) = rsq*fpair
            fx(k) = fx(k)*fpair; fy(k) = fy(k)*fpair; fz(k) = fz(k)*fpair
        end do
    end subroutine pair_forces_smooth_energy

    !> Separations (xi, yi, zi) - x(:, j) of atom i from its neighbours j = nbrs(1:nn) into fx, fy,
    !> fz (scalar loads, contiguous stores).
    pure subroutine separations(xi, yi, zi, x, nbrs, fx, fy, fz)
        real(dp), intent(in) :: xi, yi, zi
        real(dp), intent(in), contiguous :: x(:, :)
        integer, intent(in), contiguous :: nbrs(:)
        real(dp), intent(inout), contiguous :: fx(:), fy(:), fz(:)
        integer :: k, j
        !GCC$ novector
        do k = 1, size(nbrs)
            j = nbrs(k)
            fx(k) = xi - x(1, j); fy(k) = yi - x(2, j); fz(k) = zi - x(3, j)
        end do
    end subroutine separations

    !> All-pairs path for small scenes (no list). Owned pairs i < j are counted once with both
    !> forces; pairs of an owned atom with a replicated atom of another rank (ghost) give the force
    !> on the owned atom only and half the energy and virial (the other rank holds the other half).
    module subroutine lj_compute_all_pairs(self, atoms, energy, virial)
        class(lj_t), intent(in) :: self
        type(atoms_t), intent(inout) :: atoms
        real(dp), intent(out) :: energy, virial
        integer :: i, j, ti, tj, nlocal, nall
        real(dp) :: dx, dy, dz, rsq, r2inv, r6inv, fpair, e, r, scale
        nlocal = atoms%nlocal; nall = atoms%nlocal + atoms%nghost
        energy = 0; virial = 0
        do i = 1, nlocal
            ti = atoms%type(i)
            do j = i + 1, nall
                tj = atoms%type(j)
                dx = atoms%x(1, i) - atoms%x(1, j); dy = atoms%x(2, i) - atoms%x(2, j); dz = atoms%x(3, i) - atoms%x(3, j)
                rsq = dx*dx + dy*dy + dz*dz
                if (rsq >= self%cutsq(tj, ti)) cycle
                r2inv = 1/rsq
                r6inv = r2inv*r2inv*r2inv
                fpair = r6inv*(self%lj1(tj, ti)*r6inv - self%lj2(tj, ti))*r2inv
                e = r6inv*(self%lj3(tj, ti)*r6inv - self%lj4(tj, ti)) - self%offset(tj, ti)
                if (self%smooth) then
                    r = sqrt(rsq)
                    fpair = fpair - self%fc(tj, ti)/r
                    e = e + (r - self%rc(tj, ti))*self%fc(tj, ti)
                end if
                scale = 1
                if (j > nlocal) scale = 0.5_dp
                atoms%f(1, i) = atoms%f(1, i) + dx*fpair
                atoms%f(2, i) = atoms%f(2, i) + dy*fpair
                atoms%f(3, i) = atoms%f(3, i) + dz*fpair
                if (j <= nlocal) then
                    atoms%f(1, j) = atoms%f(1, j) - dx*fpair
                    atoms%f(2, j) = atoms%f(2, j) - dy*fpair
                    atoms%f(3, j) = atoms%f(3, j) - dz*fpair
                end if
                energy = energy + scale*e
                virial = virial + scale*rsq*fpair
            end do
        end do
    end subroutine lj_compute_all_pairs

    ! (lj_terms, pad_rows, select_by_type: included where they are called, so that they inline)
    include 'lj_pair_helpers.inc'

end submodule terrace_lj_force
