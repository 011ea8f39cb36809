!> EAM ray pass (terrace_eam, energy stepping): V, dV/ds, d2V/ds2 and W along x + s v, staged over
!> the full neighbourhood of each owned atom (densities, then the embedding and pair terms).
submodule (terrace_eam) terrace_eam_ray
    implicit none

contains

    !> Energy stepping's ray pass: out = (V, dV/ds, d2V/ds2, W) along x + s v (every atom, ghosts
    !> included, moves with its own velocity): this rank's share; the caller sums over ranks (the
    !> only communication). Needs the list built with want_below.
    !>
    !> Design (no reverse sum): V = sum_pairs phi + sum_owned F(rho_i). The pair part runs over the
    !> half list (each pair once across ranks). The embedding part needs rho_i, rho_i', rho_i'' of
    !> every owned atom complete on this rank. Ghosts exist within cutoff + skin of the subdomain,
    !> so every owned atom's whole neighbourhood is here: the half list's owned-owned pairs add to
    !> both atoms, its owned-ghost pairs to the owned atom only, and list%below (the ghosts the half
    !> list leaves to their owners) completes the neighbourhood of each owned atom. Ghost
    !> densities are never formed; each pair's density terms are thus evaluated once per owning
    !> rank of each end (twice for pairs across ranks), the pair energy once. Along the ray, with
    !> d = x_i - x_j and w = v_i - v_j at s, r' = d.w/r, r'' = (|w|^2 - r'^2)/r:
    !>   rho_i' = sum_j f'(r) r',   rho_i'' = sum_j f''(r) r'^2 + f'(r) r'',
    !>   V' += F'(rho_i) rho_i' + phi'(r) r',   V'' += F''(rho_i) rho_i'^2 + F'(rho_i) rho_i'' + phi'' r'^2 + phi' r''.
    !> The virial -sum_pairs r psi'(r) splits into -sum_pairs r phi'(r) - sum_owned F'(rho_i) sum_j r f_ji'(r),
    !> the inner sum gathered per owned atom like rho. Derivatives of the interpolants are those of
    !> the cubic pieces (y'' = (2 c0 p + c1)/h); where F is continued (rho beyond the table) F' is
    !> the held slope of the force pass and F'' = 0.
    module subroutine eam_ray(self, atoms, list, s, out)
        class(eam_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        type(neighbor_list_t), intent(in) :: list
        real(dp), intent(in) :: s
        real(dp), intent(out) :: out(4)
        integer :: n
        real(dp) :: lo, hi
        n = atoms%nlocal
        out = 0
        if (n == 0) return
        if (allocated(self%ray_acc)) then
            if (size(self%ray_acc, 2) < n) deallocate (self%ray_acc)
        end if
        if (.not. allocated(self%ray_acc)) allocate (self%ray_acc(4, n + n/4 + 16))
        call reserve_work(self, n, list%first)
        call reserve_work(self, n, list%below_first)
        if (self%ntypes == 1) then    ! (tfirst not read: the rows' first stands in)
            call ray_staged(self, n, atoms%x, atoms%v, atoms%type, list%first, list%neigh, list%first, &
                            list%below_first, list%below, s, self%ray_acc, out)
        else if (list%type_order == self%ntypes) then
            call ray_staged(self, n, atoms%x, atoms%v, atoms%type, list%first, list%neigh, list%tfirst, &
                            list%below_first, list%below, s, self%ray_acc, out)
        else
            call ordered_copy(self, list, atoms%type, n)
            call ray_staged(self, n, atoms%x, atoms%v, atoms%type, list%first, self%oneigh, self%otfirst, &
                            list%below_first, list%below, s, self%ray_acc, out)
        end if
        call ray_embed(n, atoms%type, self%t2f, self%fspl, self%rdrho, self%nrho, self%rhomax, self%ray_acc, out, lo, hi)
        self%rho_low = min(self%rho_low, lo)
        self%rho_high = max(self%rho_high, hi)
        if (lo < 0 .or. hi > self%rhomax) self%rho_outside = .true.
    end subroutine eam_ray

    !> Pair terms of the ray (half list) and the per-atom density sums acc(1:4, i) = (rho, rho',
    !> rho'', sum_j r f') of owned atoms (half list + below list), staged like force_one: per atom,
    !> each pair's |d|^2, d.w and |w|^2 (separation d, relative velocity w at s) gathered into rows,
    !> the pairs inside the cutoff compacted without branches, r, 1/r, r', r'', knot and offset
    !> vectorised, then the lookups. One type: the tables are fixed for the pass. Several types: the
    !> half list's rows are ordered by type (tfirst, as list%tfirst), so the tables (t2z, t2rho) are
    !> fixed per segment (the ray pass of the CuNi alloy an eighth cheaper than with each pair's
    !> types read in the lookup loop, phase_ab.sh); the complement's pairs read their neighbour's
    !> type.
    subroutine ray_staged(self, nlocal, x, v, type, first, neigh, tfirst, bfirst, below, s, acc, out)
        type(eam_t), intent(inout) :: self
        integer, intent(in) :: nlocal
        real(dp), intent(in), contiguous :: x(:, :), v(:, :)
        integer, intent(in), contiguous :: type(:), first(:), neigh(:), bfirst(:), below(:)
        integer, intent(in) :: tfirst(*)   ! several types: the rows' segments by type (list%tfirst)
        real(dp), intent(in) :: s
        real(dp), intent(inout), contiguous :: acc(:, :)
        real(dp), intent(inout) :: out(4)
        integer :: i, j, k, m, nin, a, b, c, ti, tj, bi, bj, g, k1, k2, lim
        real(dp) :: xi, yi, zi, vxi, vyi, vzi, p, top, cutsq, rdr, r, rinv, rp, z, zp, zpp, phi, phip, phipp, &
                    f0, f1, f2, e, e1, e2, w, a1, a2, a3, a4, q1, q2, ei, ce
        logical :: one
        top = self%nr - 1; cutsq = self%cutsq; rdr = self%rdr
        one = self%ntypes == 1
        a = self%t2rho(1, 1); c = self%t2z(1, 1)
        e = 0; e1 = 0; e2 = 0; w = 0; ce = 0
        acc(:, 1:nlocal) = 0
        associate (sr => self%rspl(:, :, a), sz => self%zspl(:, :, c), rs => self%rspl, zs => self%zspl, &
                   rr => self%work(:, 7), pp => self%work(:, 8), rpv => self%work(:, 9), rppv => self%work(:, 10), &
                   rv => self%work(:, 11), kk => self%iwork(:, 1), mm => self%iwork(:, 2))
        do i = 1, nlocal
            vxi = v(1, i); vyi = v(2, i); vzi = v(3, i)
            xi = x(1, i) + s*vxi; yi = x(2, i) + s*vyi; zi = x(3, i) + s*vzi
            ti = type(i)
            a1 = 0; a2 = 0; a3 = 0; a4 = 0; ei = 0
            ! the half list (pair terms; densities of i and of owned j), then the complement (density of i)
            call stage(neigh, first(i) - 1, first(i + 1) - first(i))
            ! (two versions of each lookup loop: one loop with the per-pair tables behind tests on
            ! `one` and the density terms in a procedure made the ray pass 25 % slower on 108 Cu atoms
            ! and 18 % on the CuNi alloy, phase_ab.sh)
            if (one) then
                do k = 1, nin
                    m = mm(k); p = pp(k); r = rv(k); rinv = rr(k); rp = rpv(k)
                    z = ((sz(4, m)*p + sz(5, m))*p + sz(6, m))*p + sz(7, m)
                    zp = (sz(1, m)*p + sz(2, m))*p + sz(3, m)
                    zpp = (2*sz(1, m)*p + sz(2, m))*rdr
                    phi = z*rinv
                    phip = (zp - phi)*rinv
                    phipp = (zpp - 2*phip)*rinv
                    ei = ei + phi; e1 = e1 + phip*rp; e2 = e2 + phipp*rp*rp + phip*rppv(k); w = w - r*phip
                    f0 = ((sr(4, m)*p + sr(5, m))*p + sr(6, m))*p + sr(7, m)
                    f1 = (sr(1, m)*p + sr(2, m))*p + sr(3, m)
                    f2 = (2*sr(1, m)*p + sr(2, m))*rdr
                    q1 = f1*rp
                    q2 = f2*rp*rp + f1*rppv(k)
                    a1 = a1 + f0; a2 = a2 + q1; a3 = a3 + q2; a4 = a4 + r*f1
                    j = neigh(first(i) - 1 + kk(k))
                    if (j <= nlocal) then
                        acc(1, j) = acc(1, j) + f0; acc(2, j) = acc(2, j) + q1
                        acc(3, j) = acc(3, j) + q2; acc(4, j) = acc(4, j) + r*f1
                    end if
                end do
            else
                ! segment by segment of the row ordered by type (the staged pairs keep the list's
                ! order: those of segment tj are the next ones up to its end): tables fixed per segment
                g = (i - 1)*self%ntypes
                k2 = 0
                do tj = 1, self%ntypes
                    k1 = k2 + 1
                    lim = tfirst(g + tj + 1) - first(i)
                    do k = k1, nin
                        k2 = k2 + merge(1, 0, kk(k) <= lim)
                    end do
                    c = self%t2z(ti, tj)
                    bi = self%t2rho(tj, ti)     ! density at i from j
                    bj = self%t2rho(ti, tj)     ! density at j from i
                    do k = k1, k2
                        j = neigh(first(i) - 1 + kk(k))
                        m = mm(k); p = pp(k); r = rv(k); rinv = rr(k); rp = rpv(k)
                        z = ((zs(4, m, c)*p + zs(5, m, c))*p + zs(6, m, c))*p + zs(7, m, c)
                        zp = (zs(1, m, c)*p + zs(2, m, c))*p + zs(3, m, c)
                        zpp = (2*zs(1, m, c)*p + zs(2, m, c))*rdr
                        phi = z*rinv
                        phip = (zp - phi)*rinv
                        phipp = (zpp - 2*phip)*rinv
                        ei = ei + phi; e1 = e1 + phip*rp; e2 = e2 + phipp*rp*rp + phip*rppv(k); w = w - r*phip
                        f0 = ((rs(4, m, bi)*p + rs(5, m, bi))*p + rs(6, m, bi))*p + rs(7, m, bi)
                        f1 = (rs(1, m, bi)*p + rs(2, m, bi))*p + rs(3, m, bi)
                        f2 = (2*rs(1, m, bi)*p + rs(2, m, bi))*rdr
                        a1 = a1 + f0; a2 = a2 + f1*rp; a3 = a3 + (f2*rp*rp + f1*rppv(k)); a4 = a4 + r*f1
                        if (j <= nlocal) then
                            f0 = ((rs(4, m, bj)*p + rs(5, m, bj))*p + rs(6, m, bj))*p + rs(7, m, bj)
                            f1 = (rs(1, m, bj)*p + rs(2, m, bj))*p + rs(3, m, bj)
                            f2 = (2*rs(1, m, bj)*p + rs(2, m, bj))*rdr
                            acc(1, j) = acc(1, j) + f0; acc(2, j) = acc(2, j) + f1*rp
                            acc(3, j) = acc(3, j) + (f2*rp*rp + f1*rppv(k)); acc(4, j) = acc(4, j) + r*f1
                        end if
                    end do
                end do
            end if
            call stage(below, bfirst(i) - 1, bfirst(i + 1) - bfirst(i))
            if (one) then
                do k = 1, nin
                    m = mm(k); p = pp(k); r = rv(k); rp = rpv(k)
                    f0 = ((sr(4, m)*p + sr(5, m))*p + sr(6, m))*p + sr(7, m)
                    f1 = (sr(1, m)*p + sr(2, m))*p + sr(3, m)
                    f2 = (2*sr(1, m)*p + sr(2, m))*rdr
                    a1 = a1 + f0; a2 = a2 + f1*rp; a3 = a3 + f2*rp*rp + f1*rppv(k); a4 = a4 + r*f1
                end do
            else
                do k = 1, nin
                    b = self%t2rho(type(below(bfirst(i) - 1 + kk(k))), ti)
                    m = mm(k); p = pp(k); r = rv(k); rp = rpv(k)
                    f0 = ((rs(4, m, b)*p + rs(5, m, b))*p + rs(6, m, b))*p + rs(7, m, b)
                    f1 = (rs(1, m, b)*p + rs(2, m, b))*p + rs(3, m, b)
                    f2 = (2*rs(1, m, b)*p + rs(2, m, b))*rdr
                    a1 = a1 + f0; a2 = a2 + f1*rp; a3 = a3 + (f2*rp*rp + f1*rppv(k)); a4 = a4 + r*f1
                end do
            end if
            acc(1, i) = acc(1, i) + a1; acc(2, i) = acc(2, i) + a2
            acc(3, i) = acc(3, i) + a3; acc(4, i) = acc(4, i) + a4
            call comp_add(e, ce, ei)
        end do
        end associate
        out = out + [e + ce, e1, e2, w]
    contains
        !> Rows for the nn neighbours list(k0+1 : k0+nn) of atom i: the nin inside the cutoff, with
        !> r (rv), 1/r (rr), r' (rpv), r'' (rppv), knot (mm), offset (pp) and list position (kk).
        !> The gather forms each pair's |d|^2, d.w and |w|^2 (three rows, not d and w: six rows
        !> stored, compacted and read again cost a fifth more per ray evaluation in the LJ pass).
        subroutine stage(list, k0_, nn_)
            integer, intent(in), contiguous :: list(:)
            integer, intent(in) :: k0_, nn_
            integer :: q, jj, mq
            real(dp) :: ddx, ddy, ddz, dwx, dwy, dwz, rq, rinvq, rpq, pq, rsq_q, dw_q, ww_q
            associate (dw => self%work(:, 1), ww => self%work(:, 2), rr => self%work(:, 7), pp => self%work(:, 8), &
                       rpv => self%work(:, 9), rppv => self%work(:, 10), rv => self%work(:, 11), kk => self%iwork(:, 1), &
                       mm => self%iwork(:, 2))
            !GCC$ novector
            do q = 1, nn_
                jj = list(k0_ + q)
                dwx = vxi - v(1, jj); dwy = vyi - v(2, jj); dwz = vzi - v(3, jj)
                ddx = xi - (x(1, jj) + s*v(1, jj)); ddy = yi - (x(2, jj) + s*v(2, jj))
                ddz = zi - (x(3, jj) + s*v(3, jj))
                rr(q) = ddx*ddx + ddy*ddy + ddz*ddz
                dw(q) = ddx*dwx + ddy*dwy + ddz*dwz
                ww(q) = dwx*dwx + dwy*dwy + dwz*dwz
            end do
            nin = 0
            do q = 1, nn_
                rsq_q = rr(q); dw_q = dw(q); ww_q = ww(q)
                dw(nin + 1) = dw_q; ww(nin + 1) = ww_q
                pp(nin + 1) = rsq_q
                kk(nin + 1) = q
                nin = nin + merge(1, 0, rsq_q < cutsq)
            end do
            do q = 1, nin
                rq = sqrt(pp(q))
                rinvq = 1/rq
                rpq = dw(q)*rinvq
                rv(q) = rq
                rr(q) = rinvq
                rpv(q) = rpq
                rppv(q) = (ww(q) - rpq*rpq)*rinvq
                pq = rq*rdr + 1
                mq = int(min(pq, top))
                mm(q) = mq
                pp(q) = min(pq - mq, 1.0_dp)
            end do
            end associate
        end subroutine stage
    end subroutine ray_staged

    !> Embedding terms of the ray from acc(1:4, i) = (rho, rho', rho'', sum_j r f'): F(rho_i),
    !> F' rho', F'' rho'^2 + F' rho'', and the virial share -F' sum_j r f'; lo, hi: extremes of rho.
    subroutine ray_embed(n, type, t2f, fspl, rdrho, nrho, rhomax, acc, out, lo, hi)
        integer, intent(in) :: n, nrho
        integer, intent(in), contiguous :: type(:), t2f(:)
        real(dp), intent(in), contiguous :: fspl(:, :, :), acc(:, :)
        real(dp), intent(in) :: rdrho, rhomax
        real(dp), intent(inout) :: out(4)
        real(dp), intent(out) :: lo, hi
        integer :: i, m, k
        real(dp) :: p, top, rho, f0, f1, f2, e, e1, e2, w, ce
        top = nrho - 1
        e = 0; e1 = 0; e2 = 0; w = 0; ce = 0
        lo = huge(1.0_dp); hi = -huge(1.0_dp)
        do i = 1, n
            k = t2f(type(i))
            rho = acc(1, i)
            p = rho*rdrho + 1
            m = int(max(1.0_dp, min(p, top)))
            p = p - m
            if (p > 1) then
                ! held end of the table (and linear continuation above rhomax): F'' = 0
                p = 1
                f2 = 0
            else
                f2 = (2*fspl(1, m, k)*p + fspl(2, m, k))*rdrho
            end if
            f1 = (fspl(1, m, k)*p + fspl(2, m, k))*p + fspl(3, m, k)
            f0 = ((fspl(4, m, k)*p + fspl(5, m, k))*p + fspl(6, m, k))*p + fspl(7, m, k)
            if (rho > rhomax) f0 = f0 + f1*(rho - rhomax)
            call comp_add(e, ce, f0)
            e1 = e1 + f1*acc(2, i)
            e2 = e2 + f2*acc(2, i)**2 + f1*acc(3, i)
            w = w - f1*acc(4, i)
            lo = min(lo, rho); hi = max(hi, rho)
        end do
        out = out + [e + ce, e1, e2, w]
    end subroutine ray_embed

end submodule terrace_eam_ray
