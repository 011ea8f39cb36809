!> Lennard-Jones ray passes (terrace_lj, energy stepping): V, dV/ds, d2V/ds2 and W along x + s v over
!> the half list (one type, several types, the general path with smooth terms) and over all pairs.
submodule (terrace_lj) terrace_lj_ray
    implicit none

    !> +Infinity: 1/inf = 0 masks pairs beyond the cutoff without a branch (GCC if-converts a
    !> select of two values, not a division that might trap). Read through a volatile so that GCC
    !> cannot fold 1/inf and turn the select back into a branch around the division.
    real(dp), volatile, save :: infinity = transfer(9218868437227405312_int64, 1.0_dp)
    !> 1 and 0 read through volatiles for the 0/1 factor "inside the cutoff" (GCC would otherwise
    !> split x * merge(1, 0, c) into a branch around x * 0, which it may not if-convert either).
    real(dp), volatile, save :: one = 1, zero = 0

contains

    !> Ray pass: out = (f, f', f'', virial) of the pairs this rank holds (half list, or all pairs),
    !> at positions x + s v (owned and ghost atoms; nothing is moved and no force is stored).
    module subroutine lj_ray_any(self, atoms, list, s, out)
        class(lj_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        type(neighbor_list_t), intent(in) :: list
        real(dp), intent(in) :: s
        real(dp), intent(out) :: out(4)
        if (list%all_pairs) then
            call self%ray_all_pairs(atoms, s, out)
        else if (self%ntypes == 1 .and. .not. self%smooth) then
            call reserve_work(self, list, atoms%nlocal)
            call ray_positions(self, atoms, s)
            call ray_one_type(atoms%nlocal, self%xv, list%first, list%neigh, self%lj1(1, 1), self%lj2(1, 1), &
                              self%lj3(1, 1), self%lj4(1, 1), self%cutsq(1, 1), self%offset(1, 1), infinity, one, zero, &
                              self%work(:, 1), self%work(:, 2), self%work(:, 3), self%atom_sums, out)
        else if (.not. self%smooth) then
            call reserve_work(self, list, atoms%nlocal)
            call ray_positions(self, atoms, s)
            if (list%want_types) then
                call ray_types(self, atoms%nlocal, self%xv, atoms%type, list%first, list%neigh, list%ntype, infinity, &
                               one, zero, self%work, self%atom_sums, out)
            else
                call gather_neighbour_types(list, atoms%type, atoms%nlocal, self%type_row)
                call ray_types(self, atoms%nlocal, self%xv, atoms%type, list%first, list%neigh, self%type_row, infinity, &
                               one, zero, self%work, self%atom_sums, out)
            end if
        else
            call reserve_work(self, list, atoms%nlocal)
            call ray_general(self, atoms, list%first, list%neigh, s, self%atom_sums, out)
        end if
    end subroutine lj_ray_any

    !> Ray pass, one type: per atom a gather of each pair's |d|^2, d.w and |w|^2 (separation d,
    !> relative velocity w at s: ray_rows, eight or four neighbours at a time), then one branch-free
    !> vectorised pass that computes the four per-pair terms (the cutoff is a mask: 1/rsq of an
    !> "infinite" separation) and adds them into eight lanes per term as it goes (storing four rows
    !> and summing them in a second pass made the ray pass 25 % slower on the 32,000-atom liquid).
    subroutine ray_one_type(nlocal, xv, first, neigh, lj1_, lj2_, lj3_, lj4_, cutsq_, offset_, inf, one_, zero_, &
                            rr, dw, ww, atom_sums, out)
        integer, intent(in) :: nlocal
        integer, intent(in), contiguous :: first(:), neigh(:)
        real(dp), intent(in), contiguous :: xv(:, :)
        real(dp), intent(in) :: lj1_, lj2_, lj3_, lj4_, cutsq_, offset_, inf, one_, zero_
        real(dp), intent(inout), contiguous :: rr(:), dw(:), ww(:)
        real(dp), intent(inout) :: atom_sums(:, :)
        real(dp), intent(out) :: out(4)
        integer :: i, k, k0, nn, nnp, l, kk
        real(dp) :: rsq, r2inv, r6inv, fpair, d2psi, rho1, inside, vir, far, one, zero, la(8), lb(8), lc(8), ld(8)
        real(dp) :: p_lj1, p_lj2, p_lj3, p_lj4, p_cs, p_off, p_c7h, p_2lj2   !< the pair's coefficients (lj_ray_lanes.inc)
        p_lj1 = lj1_; p_lj2 = lj2_; p_lj3 = lj3_; p_lj4 = lj4_; p_cs = cutsq_; p_off = offset_
        p_c7h = 3.5_dp*p_lj1; p_2lj2 = 2*p_lj2
        far = inf; one = one_; zero = zero_
        vir = 0
        do i = 1, nlocal
            k0 = first(i) - 1
            nn = first(i + 1) - first(i)
            call ray_rows(i, xv, neigh(k0 + 1:k0 + nn), rr, dw, ww)
            ! the rows padded to a multiple of 8 with far, motionless pairs (all four terms exactly 0):
            ! the vectorised loops below then have no remainder
            call pad_rows(nn, rr, dw, ww, pad_far, nnp)
            ! the four terms summed in eight lanes as they are computed (no rows stored and re-read):
            ! V, dV/ds = -fpair (d.w), d2V/ds2 = psi'' rho1^2 - fpair w^2 (psi = E(rsq), rho1 = 2 d.w,
            ! psi' = -fpair/2, psi'' = (7 lj1 r^-6 - 4 lj2) r^-6 r^-4 / 2) and the virial fpair rsq
            la = 0; lb = 0; lc = 0; ld = 0
            do k = 1, nnp, 8
                do l = 1, 8
                    kk = k + l - 1
                    include 'lj_ray_lanes.inc'
                end do
            end do
            atom_sums(i, 1) = sum(la); atom_sums(i, 2) = sum(lb); atom_sums(i, 3) = sum(lc); vir = vir + sum(ld)
        end do
        out = [compensated_total(atom_sums(:, 1), nlocal), compensated_total(atom_sums(:, 2), nlocal), &
               compensated_total(atom_sums(:, 3), nlocal), vir]
    end subroutine ray_one_type

    !> Ray pass, several types (style 'lj'): ray_one_type with per-pair coefficients, selected per
    !> atom row from atom i's column of the tables by the neighbours' types (select_by_type; ntr,
    !> the list's row of them). The rows are padded to a multiple of 8 with far, motionless pairs
    !> whose coefficients are 0 (all four terms exactly 0). Columns of work: |d|^2, d.w, |w|^2 1-3,
    !> lj1, lj2, cutsq, lj3, lj4, offset 4-9 (as in the force pass).
    subroutine ray_types(self, nlocal, xv, type, first, neigh, ntr, inf, one_, zero_, work, atom_sums, out)
        type(lj_t), intent(in) :: self
        integer, intent(in) :: nlocal
        integer, intent(in), contiguous :: type(:), first(:), neigh(:), ntr(:)
        real(dp), intent(in), contiguous :: xv(:, :)
        real(dp), intent(in) :: inf, one_, zero_
        real(dp), intent(inout), contiguous, target :: work(:, :)
        real(dp), intent(inout) :: atom_sums(:, :)
        real(dp), intent(out) :: out(4)
        integer :: i, k, k0, nn, nnp, l, kk, ti
        real(dp) :: rsq, r2inv, r6inv, fpair, d2psi, rho1, inside, vir, far, one, zero, la(8), lb(8), lc(8), ld(8)
        real(dp) :: p_lj1, p_lj2, p_lj3, p_lj4, p_cs, p_off, p_c7h, p_2lj2   !< the pair's coefficients (lj_ray_lanes.inc)
        real(dp), pointer, contiguous :: rr(:), dw(:), ww(:), c1(:), c2(:), cs(:), c3(:), c4(:), co(:)
        rr => work(:, 1); dw => work(:, 2); ww => work(:, 3)
        c1 => work(:, 4); c2 => work(:, 5); cs => work(:, 6); c3 => work(:, 7); c4 => work(:, 8); co => work(:, 9)
        far = inf; one = one_; zero = zero_
        vir = 0
        do i = 1, nlocal
            k0 = first(i) - 1
            nn = first(i + 1) - first(i)
            ti = type(i)
            call ray_rows(i, xv, neigh(k0 + 1:k0 + nn), rr, dw, ww)
            call select_by_type(nn, self%ntypes, ntr(k0 + 1:), self%lj1(:, ti), self%lj2(:, ti), self%cutsq(:, ti), c1, c2, &
                                cs)
            call select_by_type(nn, self%ntypes, ntr(k0 + 1:), self%lj3(:, ti), self%lj4(:, ti), self%offset(:, ti), c3, &
                                c4, co)
            call pad_rows(nn, rr, dw, ww, pad_far, nnp)
            call pad_rows(nn, c1, c2, cs, 0.0_dp, nnp)
            call pad_rows(nn, c3, c4, co, 0.0_dp, nnp)
            la = 0; lb = 0; lc = 0; ld = 0
            do k = 1, nnp, 8
                do l = 1, 8
                    kk = k + l - 1
                    p_cs = cs(kk); p_lj1 = c1(kk); p_lj2 = c2(kk); p_lj3 = c3(kk); p_lj4 = c4(kk); p_off = co(kk)
                    p_c7h = 3.5_dp*c1(kk); p_2lj2 = 2*c2(kk)
                    include 'lj_ray_lanes.inc'
                end do
            end do
            atom_sums(i, 1) = sum(la); atom_sums(i, 2) = sum(lb); atom_sums(i, 3) = sum(lc); vir = vir + sum(ld)
        end do
        out = [compensated_total(atom_sums(:, 1), nlocal), compensated_total(atom_sums(:, 2), nlocal), &
               compensated_total(atom_sums(:, 3), nlocal), vir]
    end subroutine ray_types

    !> The ray passes' rows of atom i: for its neighbours j = nbrs(:), with the separation
    !> d = x_i - x_j and the relative velocity w = v_i - v_j at the ray's s (from xv = (x + s v, v)),
    !> the three scalars the pair terms need: rr = |d|^2, dw = d.w, ww = |w|^2 (contiguous stores).
    !> Forming them here rather than storing d and w (six rows, read again by the vectorised pass)
    !> made a ray evaluation about a fifth cheaper. The gather itself is src/potentials/lj_simd.c:
    !> eight neighbours at a time with AVX-512, four with AVX2, the same bits as the scalar loop.
    pure subroutine ray_rows(i, xv, nbrs, rr, dw, ww)
        integer, intent(in) :: i
        real(dp), intent(in) :: xv(6, *)
        integer, intent(in), contiguous :: nbrs(:)
        real(dp), intent(inout), contiguous :: rr(:), dw(:), ww(:)
        call c_ray_rows(i, xv, nbrs, size(nbrs), rr, dw, ww)
    end subroutine ray_rows

    !> self%xv(:, i) = (x_i + s v_i, v_i) for every atom, owned and ghost (grown as needed).
    subroutine ray_positions(self, atoms, s)
        class(lj_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        real(dp), intent(in) :: s
        integer :: n, i
        n = atoms%nall()
        if (allocated(self%xv)) then
            if (size(self%xv, 2) < n) deallocate (self%xv)
        end if
        if (.not. allocated(self%xv)) allocate (self%xv(6, max(n + n/4, 1)))
        do i = 1, n
            self%xv(1:3, i) = atoms%x(:, i) + s*atoms%v(:, i)
            self%xv(4:6, i) = atoms%v(:, i)
        end do
    end subroutine ray_positions

    !> Ray pass, several types or lj/smooth/linear: pair by pair, summed per atom, the per-atom
    !> sums of V, V', V'' totalled by a compensated sum.
    subroutine ray_general(self, atoms, first, neigh, s, atom_sums, out)
        type(lj_t), intent(in) :: self
        type(atoms_t), intent(in) :: atoms
        integer, intent(in), contiguous :: first(:), neigh(:)
        real(dp), intent(in) :: s
        real(dp), intent(inout) :: atom_sums(:, :)
        real(dp), intent(out) :: out(4)
        integer :: i, k, j
        real(dp) :: acc(4), ai(4)
        out = 0
        do i = 1, atoms%nlocal
            ai = 0
            do k = first(i), first(i + 1) - 1
                j = neigh(k)
                call ray_pair(self, atoms, i, j, s, acc)
                ai = ai + acc
            end do
            atom_sums(i, 1:3) = ai(1:3); out(4) = out(4) + ai(4)
        end do
        do k = 1, 3
            out(k) = compensated_total(atom_sums(:, k), atoms%nlocal)
        end do
    end subroutine ray_general

    !> One pair's contribution to (f, f', f'', virial) along the ray (general path).
    pure subroutine ray_pair(self, atoms, i, j, s, acc)
        type(lj_t), intent(in) :: self
        type(atoms_t), intent(in) :: atoms
        integer, intent(in) :: i, j
        real(dp), intent(in) :: s
        real(dp), intent(out) :: acc(4)
        integer :: ti, tj
        real(dp) :: d(3), w(3), rsq, r2inv, r6inv, fpair, dpsi, d2psi, rho1, e, r
        acc = 0
        ti = atoms%type(i); tj = atoms%type(j)
        w = atoms%v(:, i) - atoms%v(:, j)
        d = (atoms%x(:, i) + s*atoms%v(:, i)) - (atoms%x(:, j) + s*atoms%v(:, j))
        rsq = sum(d*d)
        if (rsq >= self%cutsq(tj, ti)) return
        r2inv = 1/rsq
        r6inv = r2inv*r2inv*r2inv
        fpair = r6inv*(self%lj1(tj, ti)*r6inv - self%lj2(tj, ti))*r2inv
        e = r6inv*(self%lj3(tj, ti)*r6inv - self%lj4(tj, ti)) - self%offset(tj, ti)
        dpsi = -0.5_dp*fpair
        d2psi = 0.5_dp*(7*self%lj1(tj, ti)*r6inv - 4*self%lj2(tj, ti))*r6inv*r2inv*r2inv
        if (self%smooth) then
            r = sqrt(rsq)
            e = e + (r - self%rc(tj, ti))*self%fc(tj, ti)
            dpsi = dpsi + self%fc(tj, ti)/(2*r)
            d2psi = d2psi - self%fc(tj, ti)/(4*r*rsq)
            fpair = fpair - self%fc(tj, ti)/r
        end if
        rho1 = 2*sum(d*w)
        acc = [e, dpsi*rho1, d2psi*rho1*rho1 + dpsi*2*sum(w*w), fpair*rsq]
    end subroutine ray_pair

    !> Ray pass for the all-pairs path (pairs with replicated atoms count one half).
    module subroutine lj_ray_all_pairs(self, atoms, s, out)
        class(lj_t), intent(in) :: self
        type(atoms_t), intent(in) :: atoms
        real(dp), intent(in) :: s
        real(dp), intent(out) :: out(4)
        integer :: i, j, nlocal, nall
        real(dp) :: acc(4)
        nlocal = atoms%nlocal; nall = atoms%nlocal + atoms%nghost
        out = 0
        do i = 1, nlocal
            do j = i + 1, nall
                call ray_pair(self, atoms, i, j, s, acc)
                if (j > nlocal) acc = 0.5_dp*acc
                out = out + acc
            end do
        end do
    end subroutine lj_ray_all_pairs

    ! (lj_terms, pad_rows, select_by_type: included where they are called, so that they inline)
    include 'lj_pair_helpers.inc'

end submodule terrace_lj_ray
