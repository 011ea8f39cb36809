!> EAM force passes (terrace_eam): the density pass over the half list (one type, several types by
!> type segments), the embedding terms, the force pass with its per-pair staging; the tables the
!> passes read (r-tables, z-tables, pair tables), built at their first use.
submodule (terrace_eam) terrace_eam_force
    implicit none

contains

    !> Density pass over the half list, reverse sum of the ghost densities into their owners,
    !> F'(rho) of the owned atoms, forward copy of F'(rho) to the ghosts, force pass. energy = pair +
    !> embedding energy of this rank (when want_energy), virial of its pairs.
    module subroutine eam_forces(self, atoms, list, halo, want_energy, energy, virial)
        class(eam_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        type(neighbor_list_t), intent(in) :: list
        class(halo_ops_t), intent(inout) :: halo
        logical, intent(in) :: want_energy
        real(dp), intent(out) :: energy, virial
        integer :: nall
        real(dp) :: e_embed, e_pair
        nall = atoms%nall()
        call self%density(atoms, list)
        if (allocated(self%halo_buf)) then
            if (size(self%halo_buf, 2) < nall) deallocate (self%halo_buf)
        end if
        if (.not. allocated(self%halo_buf)) allocate (self%halo_buf(1, nall + nall/4 + 16))
        self%halo_buf(1, 1:nall) = self%rho(1:nall)
        call halo%reverse_sum(self%halo_buf(:, 1:nall))
        self%rho(1:atoms%nlocal) = self%halo_buf(1, 1:atoms%nlocal)
        call self%embed(atoms, want_energy, e_embed)
        self%halo_buf(1, 1:nall) = self%fp(1:nall)
        call halo%forward(self%halo_buf(:, 1:nall))
        self%fp(1:nall) = self%halo_buf(1, 1:nall)
        call self%force(atoms, list, want_energy, e_pair, virial)
        energy = 0
        if (want_energy) energy = e_embed + e_pair
    end subroutine eam_forces

    !> rho(1:nall) = 0, then over the half list: rho_i += rho_ba(r), rho_j += rho_ab(r) (ghosts
    !> included; the caller reverse-sums ghost values into their owners).
    module subroutine eam_density(self, atoms, list)
        class(eam_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        type(neighbor_list_t), intent(in) :: list
        integer :: nall
        nall = atoms%nlocal + atoms%nghost
        call reserve(self%rho, nall, minimum=64, zero=.true.)
        call reserve(self%fp, nall, minimum=64, zero=.true.)
        self%rho(1:nall) = 0
        self%kept = .false.
        if (atoms%nlocal == 0) return
        call reserve_work(self, atoms%nlocal, list%first)
        call reserve_pairs(self, atoms%nlocal, list%first)
        if (self%ntypes == 1) then
            if (.not. allocated(self%rtab)) call build_rtab(self)
            call density_one(atoms%nlocal, atoms%x, list%first, list%neigh, self%cutsq, self%rdr, self%nr, &
                             self%rtab(self%rtab0 + 1:), self%rho, self%cj, self%cfirst, self%work(:, 1), &
                             self%iwork(:, 1))
        else
            if (.not. allocated(self%dfun)) call build_pair_tables(self)
            if (list%type_order == self%ntypes) then
                call density_several(self, atoms, list%neigh, list%tfirst)
            else
                call ordered_copy(self, list, atoms%type, atoms%nlocal)
                call density_several(self, atoms, self%oneigh, self%otfirst)
            end if
        end if
        self%kept = .true.
        self%kept_n = atoms%nlocal
        self%kept_len = list%first(atoms%nlocal + 1)
    end subroutine eam_density

    !> The several-types density pass over rows ordered by type: neigh, tfirst as list%neigh,
    !> list%tfirst (the list's or ordered_copy's).
    subroutine density_several(self, atoms, neigh, tfirst)
        type(eam_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        integer, intent(in), contiguous :: neigh(:), tfirst(:)
        call density_types(atoms%nlocal, self%ntypes, atoms%x, atoms%type, tfirst, neigh, self%cutsq, self%rdr, &
                           self%nr, self%doi, self%doj, self%dfun(self%dfun0 + 1:), &
                           self%rho, self%cj, self%cfirst, self%cseg, self%work(:, 1), self%iwork(:, 1))
    end subroutine density_several

    !> The several-types pairs inside the cutoff by segment (cj, cseg), and cfirst from them, for a
    !> force pass not preceded by a density pass; neigh, tfirst as in density_several.
    subroutine segments_several(self, atoms, neigh, tfirst)
        type(eam_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        integer, intent(in), contiguous :: neigh(:), tfirst(:)
        integer :: i
        call inside_pairs(atoms%nlocal, self%ntypes, atoms%x, tfirst, neigh, self%cutsq, self%cj, self%cseg, &
                          self%work(:, 1), self%work(:, 2), self%work(:, 3), self%work(:, 4))
        do i = 1, atoms%nlocal + 1
            self%cfirst(i) = self%cseg((i - 1)*self%ntypes + 1)
        end do
    end subroutine segments_several

    !> A copy of the list's rows ordered by type (oneigh, otfirst as list%neigh, list%tfirst), for
    !> lists built without type_order.
    module subroutine ordered_copy(self, list, type, nlocal)
        type(eam_t), intent(inout) :: self
        type(neighbor_list_t), intent(in) :: list
        integer, intent(in) :: type(:), nlocal
        integer :: n, nb
        n = list%first(nlocal + 1) - 1
        nb = max(longest_row(list%first, nlocal), 1)
        call reserve(self%oneigh, max(n, 1))
        call reserve(self%otfirst, self%ntypes*nlocal + 1)
        if (allocated(self%oscratch)) then
            if (size(self%oscratch, 1) < nb + 1) deallocate (self%oscratch)
        end if
        if (.not. allocated(self%oscratch)) allocate (self%oscratch(nb + 1, 3))
        self%oneigh(1:n) = list%neigh(1:n)
        call order_rows_by_type(list%first, self%oneigh, type, nlocal, self%ntypes, self%otfirst, self%oscratch)
    end subroutine ordered_copy

    !> fp(1:nlocal) = F'(rho); energy = sum of F(rho_i) over owned atoms when want_energy (else 0).
    module subroutine eam_embed(self, atoms, want_energy, energy)
        class(eam_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        logical, intent(in) :: want_energy
        real(dp), intent(out) :: energy
        integer :: n
        real(dp) :: lo, hi
        n = atoms%nlocal
        energy = 0
        call reserve(self%fp, atoms%nlocal + atoms%nghost, minimum=64, zero=.true.)
        if (n == 0) return
        call embed_kernel(n, atoms%type, self%t2f, self%fspl, self%rdrho, self%nrho, self%rhomax, self%rho, &
                          want_energy, self%fp, energy, lo, hi)
        self%rho_low = min(self%rho_low, lo)
        self%rho_high = max(self%rho_high, hi)
        if (lo < 0 .or. hi > self%rhomax) self%rho_outside = .true.
    end subroutine eam_embed

    !> Pair and embedding forces added to atoms%f (owned and ghost) over the half list, with fp of
    !> owned and ghost atoms (the caller has forwarded fp to the ghosts). When want_energy: energy =
    !> sum of phi over the pairs held, virial = sum over them of d.F_i (else both 0). Right after
    !> `density` (same positions and list, as in `forces`) it takes the pairs inside the cutoff
    !> that the density pass found; otherwise it finds them first.
    module subroutine eam_force(self, atoms, list, want_energy, energy, virial)
        class(eam_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        type(neighbor_list_t), intent(in) :: list
        logical, intent(in) :: want_energy
        real(dp), intent(out) :: energy, virial
        energy = 0; virial = 0
        if (atoms%nlocal == 0) then
            self%kept = .false.
            return
        end if
        call reserve_work(self, atoms%nlocal, list%first)
        if (self%ntypes > 1 .and. .not. allocated(self%dfun)) call build_pair_tables(self)
        if (.not. (self%kept .and. self%kept_n == atoms%nlocal .and. self%kept_len == list%first(atoms%nlocal + 1))) then
            call reserve_pairs(self, atoms%nlocal, list%first)
            if (self%ntypes == 1) then
                call inside_pairs(atoms%nlocal, 1, atoms%x, list%first, list%neigh, self%cutsq, self%cj, self%cfirst, &
                                  self%work(:, 1), self%work(:, 2), self%work(:, 3), self%work(:, 4))
            else if (list%type_order == self%ntypes) then
                call segments_several(self, atoms, list%neigh, list%tfirst)
            else
                call ordered_copy(self, list, atoms%type, atoms%nlocal)
                call segments_several(self, atoms, self%oneigh, self%otfirst)
            end if
        end if
        self%kept = .false.
        if (self%ntypes == 1) then
            if (.not. allocated(self%ztab)) call build_ztab(self)
            call force_one(atoms%nlocal, atoms%x, atoms%f, self%cj, self%cfirst, self%rdr, self%nr, &
                           self%ztab, self%fp, want_energy, energy, virial, self%work(:, 1), self%work(:, 2), &
                           self%work(:, 3), self%work(:, 4), self%work(:, 5), self%work(:, 6), self%work(:, 7), &
                           self%work(:, 8), self%iwork(:, 2))
        else
            call force_types(atoms%nlocal, self%ntypes, atoms%x, atoms%f, atoms%type, self%cj, self%cfirst, &
                             self%cseg, self%rdr, self%nr, self%doi, self%doj, self%zoff, self%ffun, &
                             self%zfun(self%zfun0 + 1:), self%fp, want_energy, energy, virial, &
                             self%work(:, 1), self%work(:, 2), self%work(:, 3), self%work(:, 4), self%work(:, 5), &
                             self%work(:, 6), self%work(:, 7), self%work(:, 8), self%iwork(:, 2))
        end if
    end subroutine eam_force

    !> Work rows for the one-type kernels: as long as the longest row of the list (counted here from
    !> first(1:nlocal+1), which every list has, hand-built ones included).
    module subroutine reserve_work(self, nlocal, first)
        type(eam_t), intent(inout) :: self
        integer, intent(in) :: nlocal
        integer, intent(in), contiguous :: first(:)
        integer :: i, nb
        nb = 0
        do i = 1, nlocal
            nb = max(nb, first(i + 1) - first(i))
        end do
        nb = max(nb + 16, block_pairs)
        if (allocated(self%work)) then
            if (size(self%work, 1) < nb) deallocate (self%work, self%iwork)
        end if
        if (.not. allocated(self%work)) allocate (self%work(nb + nb/4, 12), self%iwork(nb + nb/4, 3))
    end subroutine reserve_work

    !> One type: the density pass's records, rho c3..c6 per knot (32 bytes, the table 64-byte
    !> aligned: a record never straddles a cache line; the rows of rspl are 56 bytes).
    subroutine build_rtab(self)
        type(eam_t), intent(inout) :: self
        integer :: n
        n = 4*self%nr
        allocate (self%rtab(n + 8))
        self%rtab0 = align_shift(self%rtab)
        self%rtab(self%rtab0 + 1:self%rtab0 + n) = reshape(self%rspl(4:7, :, self%t2rho(1, 1)), [n])
    end subroutine build_rtab

    !> One type: the force pass's lookups side by side per knot, so that a pair reads one record:
    !> t(1:3, m) = rho' coefficients (c0, c1, c2), t(4:7, m) = z coefficients (c3, c4, c5, y), as in
    !> rspl / zspl. z' is formed from z's own coefficients, ((3 c3 p + 2 c4) p + c5)/dr (what its
    !> stored c0..c2 are): 56-byte records instead of 80.
    subroutine build_ztab(self)
        type(eam_t), intent(inout) :: self
        integer :: a, c
        a = self%t2rho(1, 1); c = self%t2z(1, 1)
        allocate (self%ztab(7, self%nr))
        self%ztab(1:3, :) = self%rspl(1:3, :, a)
        self%ztab(4:7, :) = self%zspl(4:7, :, c)
    end subroutine build_ztab

    !> Several types: the tables of the density and force passes, one per function of the file (the
    !> passes pick them once per segment of a row ordered by type, so a pair type needs no record of
    !> its own), knots contiguous per function, function f's knot m at column (f-1) nr + m:
    !>   dfun: rho c3..c6 (the one-type density record), 64-byte aligned;
    !>   ffun: rho' c0..c2;
    !>   zfun: z = r phi c3..c6 (z' from them, as in build_ztab), 64-byte aligned;
    !> and per type pair (b, a) the column offsets of the density at the type-a atom from the type-b
    !> one (doi), at the type-b atom from the type-a one (doj), and of z_ab (zoff).
    subroutine build_pair_tables(self)
        type(eam_t), intent(inout) :: self
        integer :: ta, tb, nt, nr, nf, nz
        nt = self%ntypes; nr = self%nr
        nf = size(self%rspl, 3); nz = size(self%zspl, 3)
        allocate (self%dfun(4*nr*nf + 8), self%ffun(3, nr*nf), self%zfun(4*nr*nz + 8))
        allocate (self%doi(nt, nt), self%doj(nt, nt), self%zoff(nt, nt))
        self%dfun0 = align_shift(self%dfun)
        self%zfun0 = align_shift(self%zfun)
        self%dfun(self%dfun0 + 1:self%dfun0 + 4*nr*nf) = reshape(self%rspl(4:7, :, :), [4*nr*nf])
        self%ffun = reshape(self%rspl(1:3, :, :), [3, nr*nf])
        self%zfun(self%zfun0 + 1:self%zfun0 + 4*nr*nz) = reshape(self%zspl(4:7, :, :), [4*nr*nz])
        do ta = 1, nt
            do tb = 1, nt
                self%doi(tb, ta) = (self%t2rho(tb, ta) - 1)*nr
                self%doj(tb, ta) = (self%t2rho(ta, tb) - 1)*nr
                self%zoff(tb, ta) = (self%t2z(ta, tb) - 1)*nr
            end do
        end do
    end subroutine build_pair_tables

    !> Elements to skip from the start of a so that the rest starts on a 64-byte boundary (0..7).
    integer function align_shift(a) result(k)
        real(dp), intent(in), target :: a(:)
        integer(c_intptr_t) :: addr
        addr = transfer(c_loc(a(1)), addr)
        k = int(modulo(-addr, 64_c_intptr_t)/8)
    end function align_shift

    !> Separations (dx, dy, dz)(k) = x_i - x_j and their squares rr(k) for the nn neighbours
    !> j = neigh(k0 + k) of an atom at (xi, yi, zi): a scalar gather into contiguous rows, then a
    !> vectorised pass (for inside_pairs).
    subroutine separations(xi, yi, zi, x, neigh, k0, nn, dx, dy, dz, rr)
        real(dp), intent(in) :: xi, yi, zi
        real(dp), intent(in), contiguous :: x(:, :)
        integer, intent(in), contiguous :: neigh(:)
        integer, intent(in) :: k0, nn
        real(dp), intent(inout), contiguous :: dx(:), dy(:), dz(:), rr(:)
        integer :: k, j
        !GCC$ novector
        do k = 1, nn
            j = neigh(k0 + k)
            dx(k) = xi - x(1, j); dy(k) = yi - x(2, j); dz(k) = zi - x(3, j)
        end do
        do k = 1, nn
            rr(k) = dx(k)*dx(k) + dy(k)*dy(k) + dz(k)*dz(k)
        end do
    end subroutine separations

    !> One type: one density table. Per atom: one scalar pass gathers the separations, forms the
    !> squared distances and compacts the pairs inside the cutoff without branches (the list holds
    !> the skin shell too: a branch there is mispredicted about half the time), then their knots
    !> and offsets in a vectorised pass, then the table lookups and the scatter to rho(j). The
    !> partners inside the cutoff are kept for the force pass: cj(cfirst(i):cfirst(i+1)-1).
    subroutine density_one(nlocal, x, first, neigh, cutsq, rdr, nr, s, rho, cj, cfirst, pp, mm)
        integer, intent(in) :: nlocal, nr
        real(dp), intent(in) :: x(3, *)     ! explicit shape: constant stride in the gathers
        real(dp), intent(in) :: s(4, *)     ! density records (rho c3..c6) per knot
        integer, intent(in), contiguous :: first(:), neigh(:)
        real(dp), intent(in) :: cutsq, rdr
        real(dp), intent(inout), contiguous :: rho(:)
        integer, intent(inout), contiguous :: cj(:), cfirst(:)
        real(dp), intent(inout), contiguous :: pp(:)
        integer, intent(inout), contiguous :: mm(:)
        integer :: i, j, k, m, k0, nn, nin, c
        real(dp) :: xi, yi, zi, p, v, acc, top
        top = nr - 1
        c = 0
        cfirst(1) = 1
        do i = 1, nlocal
            xi = x(1, i); yi = x(2, i); zi = x(3, i)
            k0 = first(i) - 1
            nn = first(i + 1) - first(i)
            nin = 0
            call gather_inside(xi, yi, zi, x, neigh, k0, nn, cutsq, cj, c, pp, nin)
            do k = 1, nin
                p = sqrt(pp(k))*rdr + 1
                m = int(min(p, top))
                mm(k) = m
                pp(k) = min(p - m, 1.0_dp)
            end do
            acc = 0
            do k = 1, nin
                m = mm(k); p = pp(k)
                v = ((s(1, m)*p + s(2, m))*p + s(3, m))*p + s(4, m)
                acc = acc + v
                j = cj(c + k)
                rho(j) = rho(j) + v
            end do
            rho(i) = rho(i) + acc
            c = c + nin
            cfirst(i + 1) = c + 1
        end do
    end subroutine density_one

    !> The density passes' gather: of the nn partners j = neigh(k0 + k) of the atom at (xi, yi, zi),
    !> those inside the cutoff appended to cj(c + nin + 1 :) and their squared distances to
    !> pp(nin + 1 :), nin counting them; one scalar pass without branches (the list holds the skin
    !> shell too: a branch there is mispredicted about half the time).
    !> With AVX-512 the gather is eam_simd.c's (eight partners gathered, tested and compacted at a
    !> time; the same pairs, distances and order).
    subroutine gather_inside(xi, yi, zi, x, neigh, k0, nn, cutsq, cj, c, pp, nin)
        real(dp), intent(in) :: xi, yi, zi, cutsq
        real(dp), intent(in) :: x(3, *)
        integer, intent(in), contiguous :: neigh(:)
        integer, intent(in) :: k0, nn, c
        integer, intent(inout), contiguous :: cj(:)
        real(dp), intent(inout), contiguous :: pp(:)
        integer, intent(inout) :: nin
        integer :: k, j
        real(dp) :: ddx, ddy, ddz, rsq
        if (nn > 0) then
            k = c_gather_inside(xi, yi, zi, x, neigh(k0 + 1:), nn, cutsq, cj(c + nin + 1:), pp(nin + 1:))
            if (k >= 0) then
                nin = nin + k
                return
            end if
        end if
        !GCC$ novector
        do k = 1, nn
            j = neigh(k0 + k)
            ddx = xi - x(1, j); ddy = yi - x(2, j); ddz = zi - x(3, j)
            rsq = ddx*ddx + ddy*ddy + ddz*ddz
            cj(c + nin + 1) = j
            pp(nin + 1) = rsq
            nin = nin + merge(1, 0, rsq < cutsq)
        end do
    end subroutine gather_inside

    !> Several types: rho_i += rho_ba(r), rho_j += rho_ab(r) (a = type i, b = type j), staged as
    !> density_one, segment by segment of each row ordered by type (tfirst: the list's type_order),
    !> so that the tables are chosen once per segment: s holds one table per density function (the
    !> one-type records), rho_ba at column oi(b, a) + knot, rho_ab at oj(b, a) + knot; a pair whose
    !> two densities are one function (within a type, and eam/alloy's types of one element) reads
    !> one record and adds its value to both atoms, others read two (for CuNi.eam.alloy the table is
    !> 32 KB, where one 64-byte record per pair type and knot took 128 KB).
    !> The partners inside the cutoff are kept by segment for the force pass (cj, cseg, and cfirst).
    subroutine density_types(nlocal, nt, x, type, tfirst, neigh, cutsq, rdr, nr, oi, oj, s, rho, cj, cfirst, cseg, &
                             pp, mm)
        integer, intent(in) :: nlocal, nt, nr
        real(dp), intent(in) :: x(3, *)
        real(dp), intent(in) :: s(4, *)
        integer, intent(in), contiguous :: type(:), tfirst(:), neigh(:), oi(:, :), oj(:, :)
        real(dp), intent(in) :: cutsq, rdr
        real(dp), intent(inout), contiguous :: rho(:)
        integer, intent(inout), contiguous :: cj(:), cfirst(:), cseg(:)
        real(dp), intent(inout), contiguous :: pp(:)
        integer, intent(inout), contiguous :: mm(:)
        integer :: i, j, k, m, k0, nn, nin, c, ti, b, g, o, o2
        real(dp) :: xi, yi, zi, p, v, acc, top
        top = nr - 1
        c = 0
        cfirst(1) = 1
        cseg(1) = 1
        do i = 1, nlocal
            xi = x(1, i); yi = x(2, i); zi = x(3, i)
            ti = type(i)
            g = (i - 1)*nt
            ! the atom's segments end to end
            nin = 0
            do b = 1, nt
                k0 = tfirst(g + b) - 1
                nn = tfirst(g + b + 1) - tfirst(g + b)
                call gather_inside(xi, yi, zi, x, neigh, k0, nn, cutsq, cj, c, pp, nin)
                cseg(g + b + 1) = c + nin + 1
            end do
            ! knots of the whole row in one vectorised pass (the offsets are the segments')
            do k = 1, nin
                p = sqrt(pp(k))*rdr + 1
                m = int(min(p, top))
                mm(k) = m
                pp(k) = min(p - m, 1.0_dp)
            end do
            acc = 0
            do b = 1, nt
                o = oi(b, ti)
                o2 = oj(b, ti)
                if (o == o2) then
                    do k = cseg(g + b) - c, cseg(g + b + 1) - 1 - c
                        m = mm(k) + o; p = pp(k)
                        v = ((s(1, m)*p + s(2, m))*p + s(3, m))*p + s(4, m)
                        acc = acc + v
                        j = cj(c + k)
                        rho(j) = rho(j) + v
                    end do
                else
                    do k = cseg(g + b) - c, cseg(g + b + 1) - 1 - c
                        m = mm(k) + o; p = pp(k)
                        acc = acc + (((s(1, m)*p + s(2, m))*p + s(3, m))*p + s(4, m))
                        m = mm(k) + o2
                        j = cj(c + k)
                        rho(j) = rho(j) + (((s(1, m)*p + s(2, m))*p + s(3, m))*p + s(4, m))
                    end do
                end if
            end do
            rho(i) = rho(i) + acc
            c = c + nin
            cfirst(i + 1) = c + 1
        end do
    end subroutine density_types

    !> The pairs inside the cutoff as the density passes keep them (for a force pass not preceded by
    !> one), by segment: the nt segments of each atom's row, neigh(first(g) : first(g+1)-1) (g =
    !> (i-1) nt + b; nt = 1: the rows, first = the list's), to cj(cfirst(g) : cfirst(g+1)-1).
    subroutine inside_pairs(nlocal, nt, x, first, neigh, cutsq, cj, cfirst, dx, dy, dz, rr)
        integer, intent(in) :: nlocal, nt
        real(dp), intent(in), contiguous :: x(:, :)
        integer, intent(in), contiguous :: first(:), neigh(:)
        real(dp), intent(in) :: cutsq
        integer, intent(inout), contiguous :: cj(:), cfirst(:)
        real(dp), intent(inout), contiguous :: dx(:), dy(:), dz(:), rr(:)
        integer :: i, k, k0, nn, c, g
        c = 0
        cfirst(1) = 1
        do i = 1, nlocal
            do g = (i - 1)*nt + 1, i*nt
                k0 = first(g) - 1
                nn = first(g + 1) - first(g)
                call separations(x(1, i), x(2, i), x(3, i), x, neigh, k0, nn, dx, dy, dz, rr)
                do k = 1, nn
                    if (rr(k) < cutsq) then
                        c = c + 1
                        cj(c) = neigh(k0 + k)
                    end if
                end do
                cfirst(g + 1) = c + 1
            end do
        end do
    end subroutine inside_pairs

    !> Room for the pairs inside the cutoff: at most the list's length.
    subroutine reserve_pairs(self, nlocal, first)
        type(eam_t), intent(inout) :: self
        integer, intent(in) :: nlocal
        integer, intent(in), contiguous :: first(:)
        integer :: n
        n = first(nlocal + 1)
        if (allocated(self%cj)) then
            if (size(self%cj) < n .or. size(self%cfirst) < nlocal + 1) deallocate (self%cj, self%cfirst)
        end if
        if (.not. allocated(self%cj)) allocate (self%cj(n + n/4 + 16), self%cfirst(nlocal + nlocal/4 + 16))
        if (self%ntypes > 1) call reserve(self%cseg, self%ntypes*nlocal + 1)
    end subroutine reserve_pairs

    !> F'(rho) (and F) of owned atoms; lo, hi: extremes of rho.
    subroutine embed_kernel(n, type, t2f, fspl, rdrho, nrho, rhomax, rho, want_energy, fp, energy, lo, hi)
        integer, intent(in) :: n, nrho
        integer, intent(in), contiguous :: type(:), t2f(:)
        real(dp), intent(in), contiguous :: fspl(:, :, :), rho(:)
        real(dp), intent(in) :: rdrho, rhomax
        logical, intent(in) :: want_energy
        real(dp), intent(inout), contiguous :: fp(:)
        real(dp), intent(inout) :: energy
        real(dp), intent(out) :: lo, hi
        integer :: i, m, k
        real(dp) :: p, top, r, e, phi, ce
        top = nrho - 1
        e = 0; ce = 0
        lo = huge(1.0_dp); hi = -huge(1.0_dp)
        do i = 1, n
            k = t2f(type(i))
            r = rho(i)
            p = r*rdrho + 1
            m = int(max(1.0_dp, min(p, top)))
            p = min(p - m, 1.0_dp)
            fp(i) = (fspl(1, m, k)*p + fspl(2, m, k))*p + fspl(3, m, k)
            if (want_energy) then
                phi = ((fspl(4, m, k)*p + fspl(5, m, k))*p + fspl(6, m, k))*p + fspl(7, m, k)
                if (r > rhomax) phi = phi + fp(i)*(r - rhomax)
                call comp_add(e, ce, phi)
            end if
            lo = min(lo, r); hi = max(hi, r)
        end do
        energy = energy + (e + ce)
    end subroutine embed_kernel

    !> One type: psi'(r) = (fp_i + fp_j) rho'(r) + phi'(r), phi = z/r, phi' = (z' - phi)/r, over the
    !> pairs inside the cutoff (cj, cfirst). The pairs of consecutive atoms are taken in blocks of
    !> about block_pairs (whole atoms; long rows keep the vector loops busy): gathered separations
    !> and fp_i + fp_j, a vectorised pass for r^2, r, 1/r, the knot and the offset, the table
    !> lookups (one record per pair, t = ztab), a vectorised pass for the pair forces, then the
    !> scatter (Newton's third law) with the sums for the atoms i.
    subroutine force_one(nlocal, x, f, cj, cfirst, rdr, nr, t, fp, want_energy, energy, virial, &
                         dx, dy, dz, rr, pp, rinv, fj, ph, mm)
        integer, intent(in) :: nlocal, nr
        real(dp), intent(in) :: x(3, *)     ! explicit shape: constant stride in the gathers and scatters
        real(dp), intent(in), contiguous :: t(:, :), fp(:)
        real(dp), intent(inout) :: f(3, *)
        integer, intent(in), contiguous :: cj(:), cfirst(:)
        real(dp), intent(in) :: rdr
        logical, intent(in) :: want_energy
        real(dp), intent(inout) :: energy, virial
        real(dp), intent(inout), contiguous :: dx(:), dy(:), dz(:), rr(:), pp(:), rinv(:), fj(:), ph(:)
        integer, intent(inout), contiguous :: mm(:)
        integer :: i, i0, i1, j, k, m, c, c0, n
        real(dp) :: xi, yi, zi, fpi, p, r, rp, z, zp, phi, fpair, fxi, fyi, fzi, e, w, top, ei, ce
        top = nr - 1
        e = 0; w = 0; ce = 0
        i0 = 1
        do while (i0 <= nlocal)
            ! the block: atoms i0..i1, pairs c0+1..c0+n (at least one atom; the rows fit: reserve_work)
            c0 = cfirst(i0) - 1
            i1 = i0
            do while (i1 < nlocal)
                if (cfirst(i1 + 2) - 1 - c0 > block_pairs) exit
                i1 = i1 + 1
            end do
            n = cfirst(i1 + 1) - 1 - c0
            do i = i0, i1
                xi = x(1, i); yi = x(2, i); zi = x(3, i); fpi = fp(i)
                !GCC$ novector
                do c = cfirst(i), cfirst(i + 1) - 1
                    k = c - c0
                    j = cj(c)
                    dx(k) = xi - x(1, j); dy(k) = yi - x(2, j); dz(k) = zi - x(3, j)
                    fj(k) = fpi + fp(j)
                end do
            end do
            do k = 1, n
                rr(k) = dx(k)*dx(k) + dy(k)*dy(k) + dz(k)*dz(k)
                r = sqrt(rr(k))
                rinv(k) = 1/r
                p = r*rdr + 1
                m = int(min(p, top))
                mm(k) = m
                pp(k) = min(p - m, 1.0_dp)
            end do
            ! lookups (scalar: a vectorised gather of the record costs more): rp -> fj (times fp_i + fp_j),
            ! z' -> pp, z -> ph; rr keeps r^2, rinv becomes fpair
            !GCC$ novector
            do k = 1, n
                m = mm(k); p = pp(k)
                rp = (t(1, m)*p + t(2, m))*p + t(3, m)
                zp = ((3*t(4, m)*p + 2*t(5, m))*p + t(6, m))*rdr
                z = ((t(4, m)*p + t(5, m))*p + t(6, m))*p + t(7, m)
                fj(k) = fj(k)*rp
                pp(k) = zp
                ph(k) = z
            end do
            do k = 1, n
                phi = ph(k)*rinv(k)
                ph(k) = phi
                fpair = -(fj(k) + (pp(k)*rinv(k) - phi*rinv(k)))*rinv(k)
                rinv(k) = fpair
                dx(k) = dx(k)*fpair; dy(k) = dy(k)*fpair; dz(k) = dz(k)*fpair
            end do
            if (want_energy) then
                ! pair energies summed per atom, the atoms' sums compensated (see the top)
                do i = i0, i1
                    ei = 0
                    do c = cfirst(i), cfirst(i + 1) - 1
                        k = c - c0
                        ei = ei + ph(k)
                        w = w + rr(k)*rinv(k)
                    end do
                    call comp_add(e, ce, ei)
                end do
            end if
            do i = i0, i1
                fxi = 0; fyi = 0; fzi = 0
                !GCC$ novector
                do c = cfirst(i), cfirst(i + 1) - 1
                    k = c - c0
                    j = cj(c)
                    f(1, j) = f(1, j) - dx(k); f(2, j) = f(2, j) - dy(k); f(3, j) = f(3, j) - dz(k)
                    fxi = fxi + dx(k); fyi = fyi + dy(k); fzi = fzi + dz(k)
                end do
                f(1, i) = f(1, i) + fxi; f(2, i) = f(2, i) + fyi; f(3, i) = f(3, i) + fzi
            end do
            i0 = i1 + 1
        end do
        energy = energy + (e + ce); virial = virial + w
    end subroutine force_one

    !> Several types: psi'(r) = fp_i rho_ba'(r) + fp_j rho_ab'(r) + phi_ab'(r) (a = type i, b = type
    !> j), staged and blocked as force_one, the lookups segment by segment of the density pass's
    !> pairs (cseg), from the tables of build_pair_tables: rd (rho' c0..c2 per density function;
    !> rho_ba' at column oi(b, a) + knot, rho_ab' at oj(b, a) + knot) and zt (z c3..c6 per r phi
    !> function, z_ab at oz(b, a) + knot); z' = ((3 c3 p + 2 c4) p + c5)/dr. A pair whose two
    !> densities are one function (within a type) reads rho' once and multiplies it by fp_i + fp_j.
    subroutine force_types(nlocal, nt, x, f, type, cj, cfirst, cseg, rdr, nr, oi, oj, oz, rd, zt, fp, want_energy, &
                           energy, virial, dx, dy, dz, rr, pp, rinv, fj, ph, mm)
        integer, intent(in) :: nlocal, nt, nr
        real(dp), intent(in) :: x(3, *)
        real(dp), intent(in), contiguous :: fp(:)
        real(dp), intent(in) :: rd(3, *), zt(4, *)
        real(dp), intent(inout) :: f(3, *)
        integer, intent(in), contiguous :: type(:), cj(:), cfirst(:), cseg(:), oi(:, :), oj(:, :), oz(:, :)
        real(dp), intent(in) :: rdr
        logical, intent(in) :: want_energy
        real(dp), intent(inout) :: energy, virial
        real(dp), intent(inout), contiguous :: dx(:), dy(:), dz(:), rr(:), pp(:), rinv(:), fj(:), ph(:)
        integer, intent(inout), contiguous :: mm(:)
        integer :: i, i0, i1, j, k, m, c, c0, n, ti, b, g, o, o2, o3
        real(dp) :: xi, yi, zi, fpi, p, r, rp, rpi, rpj, z, zp, phi, fpair, fxi, fyi, fzi, e, w, top, ei, ce
        top = nr - 1
        e = 0; w = 0; ce = 0
        i0 = 1
        do while (i0 <= nlocal)
            c0 = cfirst(i0) - 1
            i1 = i0
            do while (i1 < nlocal)
                if (cfirst(i1 + 2) - 1 - c0 > block_pairs) exit
                i1 = i1 + 1
            end do
            n = cfirst(i1 + 1) - 1 - c0
            do i = i0, i1
                xi = x(1, i); yi = x(2, i); zi = x(3, i)
                !GCC$ novector
                do c = cfirst(i), cfirst(i + 1) - 1
                    k = c - c0
                    j = cj(c)
                    dx(k) = xi - x(1, j); dy(k) = yi - x(2, j); dz(k) = zi - x(3, j)
                    fj(k) = fp(j)
                end do
            end do
            do k = 1, n
                rr(k) = dx(k)*dx(k) + dy(k)*dy(k) + dz(k)*dz(k)
                r = sqrt(rr(k))
                rinv(k) = 1/r
                p = r*rdr + 1
                m = int(min(p, top))
                mm(k) = m
                pp(k) = min(p - m, 1.0_dp)
            end do
            ! lookups (scalar: see force_one), segment by segment: (fp_i + fp_j) rho_aa' or
            ! fp_i rho_ba' + fp_j rho_ab' -> fj; z' -> pp, z -> ph
            do i = i0, i1
                fpi = fp(i)
                ti = type(i)
                do b = 1, nt
                    g = (i - 1)*nt + b
                    o = oi(b, ti); o2 = oj(b, ti); o3 = oz(b, ti)
                    if (o == o2) then
                        !GCC$ novector
                        do k = cseg(g) - c0, cseg(g + 1) - 1 - c0
                            m = mm(k); p = pp(k)
                            rp = (rd(1, m + o)*p + rd(2, m + o))*p + rd(3, m + o)
                            zp = ((3*zt(1, m + o3)*p + 2*zt(2, m + o3))*p + zt(3, m + o3))*rdr
                            z = ((zt(1, m + o3)*p + zt(2, m + o3))*p + zt(3, m + o3))*p + zt(4, m + o3)
                            fj(k) = (fpi + fj(k))*rp
                            pp(k) = zp
                            ph(k) = z
                        end do
                    else
                        !GCC$ novector
                        do k = cseg(g) - c0, cseg(g + 1) - 1 - c0
                            m = mm(k); p = pp(k)
                            rpi = (rd(1, m + o)*p + rd(2, m + o))*p + rd(3, m + o)
                            rpj = (rd(1, m + o2)*p + rd(2, m + o2))*p + rd(3, m + o2)
                            zp = ((3*zt(1, m + o3)*p + 2*zt(2, m + o3))*p + zt(3, m + o3))*rdr
                            z = ((zt(1, m + o3)*p + zt(2, m + o3))*p + zt(3, m + o3))*p + zt(4, m + o3)
                            fj(k) = fpi*rpi + fj(k)*rpj
                            pp(k) = zp
                            ph(k) = z
                        end do
                    end if
                end do
            end do
            do k = 1, n
                phi = ph(k)*rinv(k)
                ph(k) = phi
                fpair = -(fj(k) + (pp(k)*rinv(k) - phi*rinv(k)))*rinv(k)
                rinv(k) = fpair
                dx(k) = dx(k)*fpair; dy(k) = dy(k)*fpair; dz(k) = dz(k)*fpair
            end do
            if (want_energy) then
                ! pair energies summed per atom, the atoms' sums compensated (see the top)
                do i = i0, i1
                    ei = 0
                    do c = cfirst(i), cfirst(i + 1) - 1
                        k = c - c0
                        ei = ei + ph(k)
                        w = w + rr(k)*rinv(k)
                    end do
                    call comp_add(e, ce, ei)
                end do
            end if
            do i = i0, i1
                fxi = 0; fyi = 0; fzi = 0
                !GCC$ novector
                do c = cfirst(i), cfirst(i + 1) - 1
                    k = c - c0
                    j = cj(c)
                    f(1, j) = f(1, j) - dx(k); f(2, j) = f(2, j) - dy(k); f(3, j) = f(3, j) - dz(k)
                    fxi = fxi + dx(k); fyi = fyi + dy(k); fzi = fzi + dz(k)
                end do
                f(1, i) = f(1, i) + fxi; f(2, i) = f(2, i) + fyi; f(3, i) = f(3, i) + fzi
            end do
            i0 = i1 + 1
        end do
        energy = energy + (e + ce); virial = virial + w
    end subroutine force_types

end submodule terrace_eam_force
