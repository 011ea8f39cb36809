!> Lennard-Jones pair potential, per type pair:
!>   E(r) = 4 eps [ (sigma/r)^12 - (sigma/r)^6 ]  - offset            (style 'lj', r < rc)
!>   offset = E_LJ(rc) when shift = .true., else 0 (truncated, unshifted: E jumps at rc)
!> style 'lj/smooth/linear' (shifted force): E(r) = E_LJ(r) - E_LJ(rc) - (r - rc) E_LJ'(rc),
!> so that energy and force both vanish at rc.
!> With lj1 = 48 eps sigma^12, lj2 = 24 eps sigma^6 the pair force on i is
!>   F_i = fpair (x_i - x_j),  fpair = r^-8 (lj1 r^-6 - lj2)  (no square root).
!> Kernels walk the half neighbour list (Newton's third law: j gets -F_i, ghosts included) and are
!> specialised: one type or several, energy+virial wanted or not, plain or smooth.
!> This file holds the type, its tables and set-up; the force passes are lj_force.inc, the ray
!> passes lj_ray.inc, the pair terms both use lj_pair_helpers.inc (included below: one compilation
!> unit, so that GCC inlines the pair loops), the fused AVX-512 kernels lj_simd.c.
!>
!> Ray pass (energy stepping): along x(s) = x + s v, with d = x_i - x_j, w = v_i - v_j and
!> rho = |d|^2 (rho' = 2 d.w, rho'' = 2 |w|^2), each pair adds psi(rho), psi' rho' and
!> psi'' rho'^2 + psi' rho'' to f, f', f'', where psi'(rho) = -fpair/2 and
!> psi''(rho) = (7 lj1 rho^-8 - 4 lj2 rho^-5)/2 (+ the smooth term (r - rc) fc: fc/(2r), -fc/(4r^3)).
!> V (and V', V'') is summed per atom and the per-atom sums are totalled by a compensated sum,
!> in the force pass as in the ray pass: the event solver decides on V to a few tens of eps |V|,
!> finer than the noise of a plain running sum over all pairs (terrace_compensated_sum).
!>
!> Mixed precision (&potential precision = 'mixed', one atom type, style 'lj'): single-precision
!> pair terms (rsq, r^-2, r^-6, fpair, the pair force, energy and virial), twice as many per SIMD
!> vector; the integrator stays double. In 3-D Verlet runs (&neighbor list = 'auto' or 'clusters')
!> over the cluster-pair list (terrace_cluster_list, kernel terrace_lj_cluster: positions relative
!> to their cluster's centre, 4 x 4 pairs per 16-lane vector); otherwise (list = 'cells', 2-D)
!> over the half atom list (kernel_mixed below: with AVX-512 the pass of lj_mixed_simd.c, fixed-point
!> positions and single force records; otherwise separations from hi and lo singles, forces summed
!> in double). The ray pass (energy stepping) is always double.
module terrace_lj
    use, intrinsic :: iso_fortran_env, only: int32, int64, sp => real32
    use, intrinsic :: iso_c_binding, only: c_int, c_double, c_float
    use terrace_kinds, only: dp
    use terrace_compensated_sum, only: compensated_total
    use terrace_grow, only: reserve
    use terrace_atoms, only: atoms_t
    use terrace_neighbor_list, only: neighbor_list_t, gather_neighbour_types, row_offsets
    use terrace_potential, only: potential_t, halo_ops_t
    use terrace_errors, only: stop_all
    use terrace_lj_cluster, only: cluster_forces
    use terrace_cluster_list, only: cluster_cutoff_limit
    implicit none
    private

    !> +Infinity: 1/inf = 0 masks pairs beyond the cutoff without a branch (GCC if-converts a
    !> select of two values, not a division that might trap). Read through a volatile so that GCC
    !> cannot fold 1/inf and turn the select back into a branch around the division.
    real(dp), volatile, save :: infinity = transfer(9218868437227405312_int64, 1.0_dp)
    !> 1 and 0 read through volatiles for the 0/1 factor "inside the cutoff" (GCC would otherwise
    !> split x * merge(1, 0, c) into a branch around x * 0, which it may not if-convert either).
    real(dp), volatile, save :: one = 1, zero = 0
    !> Pairs per block of the mixed kernel's single-precision pass (16 singles: one AVX-512 vector).
    integer, parameter :: block = 16

    !> The coefficient tables of the fused several-types pass (lj_simd.c's struct terrace_lj_tables):
    !> each table's type pairs at (1:ntypes, 1:ntypes) of an 8 x 8 array (column-major, the rest 0),
    !> filled in setup for 2 to 8 types (ntypes is set for any count; the C pass declines above 8).
    type, bind(c) :: lj_simd_tables_t
        real(c_double) :: lj1(8, 8) = 0, lj2(8, 8) = 0, lj3(8, 8) = 0, lj4(8, 8) = 0, cutsq(8, 8) = 0, offset(8, 8) = 0
        integer(c_int) :: ntypes = 0
    end type lj_simd_tables_t

    type, extends(potential_t), public :: lj_t
        integer :: ntypes = 1
        logical :: smooth = .false.
        logical :: shift = .false.
        real(dp) :: eps11 = 0, sig11 = 0         !< type 1's parameters (scene plan)
        logical :: no_cutoff = .false.
        real(dp), allocatable :: lj1(:, :), lj2(:, :), lj3(:, :), lj4(:, :), cutsq(:, :), offset(:, :)
        real(dp), allocatable :: fc(:, :)        !< smooth: -E_LJ'(rc) (force magnitude at rc)
        real(dp), allocatable :: rc(:, :)
        real(dp) :: cutmax = 0
        type(lj_simd_tables_t) :: simd           !< several types: the tables as the fused C pass reads them
        real(dp), allocatable :: work(:, :)      !< per-atom rows of pair forces (grown at rebuilds)
        integer, allocatable :: type_row(:)      !< several types, a list without types: its neighbours' types
        !> per owned atom, the sum of its pairs' energy (and, in the ray pass, V' and V'' terms):
        !> totalled by a compensated sum (see terrace_compensated_sum: why V needs it)
        real(dp), allocatable :: atom_sums(:, :)
        !> ray pass: (x + s v, v) of every atom, owned and ghost, side by side (one gather per neighbour)
        real(dp), allocatable :: xv(:, :)
        real(dp), allocatable :: ray_soa(:)      !< all-pairs ray pass: six rows of nall + 4 (lj_ray_all_pairs.c)
        !> (lj1, lj2, lj3, lj4, cutsq, offset) of types (1, 1), for the all-pairs passes of one type
        real(dp) :: c11(6) = 0
        logical :: mixed = .false.               !< single-precision pair arithmetic (one type, 'lj', half list)
        real(sp), allocatable :: xs(:, :)        !< mixed: positions as (hi, 0, lo, 0) singles, 8 per atom
        real(dp), allocatable :: fd(:, :)        !< mixed: per-atom force records (x, y, z, 0)
        integer(int32), allocatable :: xq(:, :)  !< mixed, SIMD pass: fixed-point positions (x, y, z, 0)
        real(sp), allocatable :: ff(:, :)        !< mixed, SIMD pass: single force records (x, y, z, 0)
        !> mixed, SIMD pass: the list's rows as byte offsets (padded to blocks of 16), their starts,
        !> and the list they were formed from (its build count, atoms held and length; -1: none)
        integer, allocatable :: moffs(:)
        integer, allocatable :: mofirst(:)
        integer :: mixed_key(3) = -1
        real(sp), allocatable :: rows_sp(:, :), fp_sp(:), ep_sp(:), wp_sp(:)  !< mixed: per-atom rows
        real(sp), allocatable :: xrep(:, :, :), frep(:, :, :)  !< mixed over clusters: replicated records
        integer :: cluster_build = -1            !< mixed over clusters: the list build of the last pass
    contains
        procedure :: setup => lj_setup
        procedure :: forces => lj_forces
        procedure :: ray => lj_ray_any
        procedure :: cutoff => lj_cutoff
        procedure :: describe => lj_describe
        procedure :: supports_all_pairs => lj_true
        procedure :: runs_on_pruned_list => lj_true
        procedure :: wants_neighbour_types => lj_several_types
        procedure :: wants_clusters => lj_wants_clusters
        procedure :: wraps_images => lj_wraps_images
        procedure :: contact_distance => lj_contact_distance
        procedure :: time_unit => lj_time_unit
        procedure :: cutoff_derivatives => lj_cutoff_derivatives
        procedure :: compute => lj_compute
        procedure :: compute_all_pairs => lj_compute_all_pairs
        procedure :: pair_energy => lj_pair_energy
        procedure :: ray_all_pairs => lj_ray_all_pairs
    end type lj_t

    !> A separation beyond any cutoff whose square is still finite: the pad of the rows that the
    !> eight-lane loops run over (its pair terms are exactly 0).
    real(dp), parameter :: pad_far = 1.0e100_dp

    interface
        !> The all-pairs ray pass of one type (lj_ray_all_pairs.c): c = (lj1, lj2, lj3, lj4, cutsq,
        !> offset); soa: scratch of 6 (nall + 4) doubles.
        subroutine c_ray_all_pairs(nlocal, nall, x, v, s, c, soa, out) bind(C, name='terrace_ray_all_pairs')
            import :: c_int, c_double
            integer(c_int), value :: nlocal, nall
            real(c_double), intent(in) :: x(3, *), v(3, *), c(6)
            real(c_double), value :: s
            real(c_double), intent(inout) :: soa(*)
            real(c_double), intent(out) :: out(4)
        end subroutine c_ray_all_pairs
        !> src/potentials/lj_simd.c: ray_rows's gather (neighbour indices 1-based, as here)
        pure subroutine c_ray_rows(i, xv, nbrs, nn, rr, dw, ww) bind(C, name='terrace_ray_rows')
            import :: c_int, c_double
            integer(c_int), value :: i, nn
            real(c_double), intent(in) :: xv(*)
            integer(c_int), intent(in) :: nbrs(*)
            real(c_double), intent(inout) :: rr(*), dw(*), ww(*)
        end subroutine c_ray_rows
        !> src/potentials/lj_simd.c: the fused one-type force pass (0: not in this build)
        integer(c_int) function c_lj_one_type(nlocal, x, f, first, neigh, lj1, lj2, lj3, lj4, cutsq, offset, &
                                              want_energy, atom_e, virial) bind(C, name='terrace_lj_one_type')
            import :: c_int, c_double
            integer(c_int), value :: nlocal, want_energy
            real(c_double), intent(in) :: x(*)
            real(c_double), intent(inout) :: f(*), atom_e(*), virial
            integer(c_int), intent(in) :: first(*), neigh(*)
            real(c_double), value :: lj1, lj2, lj3, lj4, cutsq, offset
        end function c_lj_one_type
        !> src/potentials/lj_simd.c: the same pass for 2 to 8 types (0: not in this build, or more types)
        integer(c_int) function c_lj_types(nlocal, x, f, first, neigh, type, ntype, tables, want_energy, atom_e, &
                                           virial) bind(C, name='terrace_lj_types')
            import :: c_int, c_double, lj_simd_tables_t
            integer(c_int), value :: nlocal, want_energy
            real(c_double), intent(in) :: x(*)
            type(lj_simd_tables_t), intent(in) :: tables
            real(c_double), intent(inout) :: f(*), atom_e(*), virial
            integer(c_int), intent(in) :: first(*), neigh(*), type(*), ntype(*)
        end function c_lj_types
        !> src/potentials/lj_mixed_simd.c: the mixed-precision pass over the half list (0: not in this
        !> build), with the list's offsets (row_offsets)
        integer(c_int) function c_lj_mixed(nlocal, nall, x, f, xq, ff, first, ofirst, offs, coeffs, want_energy, &
                                           wrapped, wrap, atom_e, virial) bind(C, name='terrace_lj_mixed')
            import :: c_int, c_double, c_float
            integer(c_int), value :: nlocal, nall, want_energy, wrapped
            real(c_double), intent(in) :: x(*), wrap(6)
            real(c_double), intent(inout) :: f(*), atom_e(*), virial
            integer(c_int), intent(inout) :: xq(*)
            real(c_float), intent(inout) :: ff(*)
            integer(c_int), intent(in) :: first(*), ofirst(*), offs(*)
            real(c_double), intent(in) :: coeffs(6)
        end function c_lj_mixed
        !> src/potentials/lj_mixed_simd.c: 1 where this build has the AVX-512 mixed pass, 2 the AVX2 one, else 0
        pure integer(c_int) function c_lj_mixed_simd() bind(C, name='terrace_lj_mixed_simd')
            import :: c_int
        end function c_lj_mixed_simd
    end interface


contains

    !> Tables from per-pair epsilon, sigma, cutoff (full symmetric ntypes x ntypes arrays).
    !> A cutoff of 0 means no cutoff (all pairs). mixed (default .false.): the mixed-precision
    !> half-list kernel; only for one type and style 'lj' (the caller checks; here it is ignored
    !> otherwise, see mixed_supported).
    subroutine lj_setup(self, ntypes, eps, sig, cut, shift, smooth, mixed)
        class(lj_t), intent(inout) :: self
        integer, intent(in) :: ntypes
        real(dp), intent(in) :: eps(:, :), sig(:, :), cut(:, :)
        logical, intent(in) :: shift, smooth
        logical, intent(in), optional :: mixed
        integer :: i, j
        real(dp) :: sr6, rc
        self%ntypes = ntypes
        self%mixed = .false.
        if (present(mixed)) self%mixed = mixed .and. mixed_supported(ntypes, smooth)
        self%smooth = smooth
        self%shift = shift
        self%eps11 = eps(1, 1); self%sig11 = sig(1, 1)
        if (allocated(self%lj1)) deallocate (self%lj1, self%lj2, self%lj3, self%lj4, self%cutsq, self%offset, self%fc, &
                                             self%rc)
        allocate (self%lj1(ntypes, ntypes), self%lj2(ntypes, ntypes), self%lj3(ntypes, ntypes), &
                  self%lj4(ntypes, ntypes), self%cutsq(ntypes, ntypes), self%offset(ntypes, ntypes), &
                  self%fc(ntypes, ntypes), self%rc(ntypes, ntypes))
        self%no_cutoff = all(cut(1:ntypes, 1:ntypes) == 0)
        do j = 1, ntypes
            do i = 1, ntypes
                self%lj1(i, j) = 48*eps(i, j)*sig(i, j)**12
                self%lj2(i, j) = 24*eps(i, j)*sig(i, j)**6
                self%lj3(i, j) = 4*eps(i, j)*sig(i, j)**12
                self%lj4(i, j) = 4*eps(i, j)*sig(i, j)**6
                rc = cut(i, j)
                self%rc(i, j) = rc
                if (rc == 0) then
                    self%cutsq(i, j) = huge(1.0_dp)
                    self%offset(i, j) = 0; self%fc(i, j) = 0
                    cycle
                end if
                self%cutsq(i, j) = rc*rc
                sr6 = (sig(i, j)/rc)**6
                self%offset(i, j) = 0
                if (shift .or. smooth) self%offset(i, j) = 4*eps(i, j)*(sr6*sr6 - sr6)
                self%fc(i, j) = 0
                if (smooth) self%fc(i, j) = 24*eps(i, j)*(2*sr6*sr6 - sr6)/rc
            end do
        end do
        self%cutmax = maxval(cut(1:ntypes, 1:ntypes))
        self%c11 = [self%lj1(1, 1), self%lj2(1, 1), self%lj3(1, 1), self%lj4(1, 1), self%cutsq(1, 1), self%offset(1, 1)]
        self%simd = lj_simd_tables_t()
        self%simd%ntypes = ntypes
        if (ntypes <= 8) then
            self%simd%lj1(1:ntypes, 1:ntypes) = self%lj1; self%simd%lj2(1:ntypes, 1:ntypes) = self%lj2
            self%simd%lj3(1:ntypes, 1:ntypes) = self%lj3; self%simd%lj4(1:ntypes, 1:ntypes) = self%lj4
            self%simd%cutsq(1:ntypes, 1:ntypes) = self%cutsq; self%simd%offset(1:ntypes, 1:ntypes) = self%offset
        end if
    end subroutine lj_setup

    !> The mixed-precision kernel exists for one atom type and style 'lj' (shifted or not).
    pure logical function mixed_supported(ntypes, smooth) result(ok)
        integer, intent(in) :: ntypes
        logical, intent(in) :: smooth
        ok = ntypes == 1 .and. .not. smooth
    end function mixed_supported

    !> The largest pair cutoff; 0 when no pair has one (all pairs interact).
    pure real(dp) function lj_cutoff(self)
        class(lj_t), intent(in) :: self
        lj_cutoff = self%cutmax
    end function lj_cutoff

    function lj_describe(self) result(text)
        class(lj_t), intent(in) :: self
        character(len=:), allocatable :: text
        character(len=256) :: s
        write (s, '(a,a,a,g0.6,a,g0.6)') trim(merge('lj/smooth/linear', 'lj              ', self%smooth)), &
            trim(merge(' (shifted)', '          ', self%shift .and. .not. self%smooth)), ', epsilon(1,1) = ', self%eps11, &
            ', sigma(1,1) = ', self%sig11
        text = trim(s)//'; no density pass (pair potential)'
        if (self%mixed .and. c_lj_mixed_simd() /= 0) then
            text = text//'; mixed precision (single-precision pairs and neighbour sums, '// &
                   trim(merge('AVX-512', 'AVX2   ', c_lj_mixed_simd() == 1))//' pass; forces in double)'
        else if (self%mixed) then
            text = text//'; mixed precision (single-precision pairs; the portable pass)'
        end if
    end function lj_describe

    !> Lennard-Jones runs on all pairs (no list) and over a pruned list (its passes use the pairs
    !> within the cutoff only).
    pure logical function lj_true(self)
        class(lj_t), intent(in) :: self
        lj_true = .true.
    end function lj_true

    !> The mixed-precision kernel can run over a cluster-pair list (3-D Verlet runs with a cell list,
    !> &neighbor list = 'clusters'); elsewhere over the atom rows ('auto' included: without AVX-512
    !> the cluster pass's speed varies too much between machines, doc/performance.md). (Cutoffs of
    !> 1000 length units and more keep the atom rows: the cluster kernel puts empty slots 10^4 away.)
    pure logical function lj_wants_clusters(self)
        class(lj_t), intent(in) :: self
        lj_wants_clusters = self%mixed .and. self%cutmax > 0 .and. self%cutmax < cluster_cutoff_limit
    end function lj_wants_clusters

    !> The mixed-precision pass with AVX-512 or AVX2 (lj_mixed_simd.c) reads a list with wrapped
    !> images: its positions in fixed point on the box's periodic grid (one type, style 'lj').
    pure logical function lj_wraps_images(self)
        class(lj_t), intent(in) :: self
        lj_wraps_images = self%mixed .and. self%ntypes == 1 .and. .not. self%smooth .and. c_lj_mixed_simd() /= 0
    end function lj_wraps_images

    !> Several types: the passes read the neighbours' types from the list (list%want_types).
    pure logical function lj_several_types(self)
        class(lj_t), intent(in) :: self
        lj_several_types = self%ntypes > 1
    end function lj_several_types

    !> sigma_ij = (lj3/lj4)^(1/6).
    pure real(dp) function lj_contact_distance(self, ti, tj)
        class(lj_t), intent(in) :: self
        integer, intent(in) :: ti, tj
        lj_contact_distance = (self%lj3(ti, tj)/max(self%lj4(ti, tj), tiny(1.0_dp)))**(1.0_dp/6)
    end function lj_contact_distance

    !> (rc, V'(rc), V''(rc), V'''(rc)) of the ti-tj pair: E_LJ's derivatives (the shift changes none;
    !> lj/smooth/linear's V' is 0 at rc); rc = 0 without a cutoff.
    pure function lj_cutoff_derivatives(self, ti, tj) result(d)
        class(lj_t), intent(in) :: self
        integer, intent(in) :: ti, tj
        real(dp) :: d(4), r, a, b
        r = self%rc(ti, tj)
        d = 0
        if (r <= 0) return
        a = self%lj3(ti, tj); b = self%lj4(ti, tj)        ! E_LJ = a r^-12 - b r^-6
        d(1) = r
        d(2) = -12*a*r**(-13) + 6*b*r**(-7)
        d(3) = 156*a*r**(-14) - 42*b*r**(-8)
        d(4) = -2184*a*r**(-15) + 336*b*r**(-9)
        if (self%smooth) d(2) = 0
    end function lj_cutoff_derivatives

    !> tau = sigma sqrt(m mvv2e / eps) of type 1.
    pure subroutine lj_time_unit(self, mass, mvv2e, tau, words)
        class(lj_t), intent(in) :: self
        real(dp), intent(in) :: mass, mvv2e
        real(dp), intent(out) :: tau
        character(len=:), allocatable, intent(out) :: words
        real(dp) :: eps, sig
        eps = self%lj4(1, 1)**2/(4*self%lj3(1, 1))
        sig = (self%lj3(1, 1)/self%lj4(1, 1))**(1.0_dp/6)
        tau = sig*sqrt(mass*mvv2e/eps)
        words = '0.005 tau, tau = sigma sqrt(m/epsilon)'
    end subroutine lj_time_unit

    !> Energy of one pair at squared distance rsq (tests and diagnostics; not a hot path).
    pure real(dp) function lj_pair_energy(self, ti, tj, rsq) result(e)
        class(lj_t), intent(in) :: self
        integer, intent(in) :: ti, tj
        real(dp), intent(in) :: rsq
        real(dp) :: r6inv, r
        e = 0
        if (rsq >= self%cutsq(ti, tj)) return
        r6inv = 1/rsq**3
        e = r6inv*(self%lj3(ti, tj)*r6inv - self%lj4(ti, tj)) - self%offset(ti, tj)
        if (self%smooth) then
            r = sqrt(rsq)
            e = e + (r - self%rc(ti, tj))*self%fc(ti, tj)
        end if
    end function lj_pair_energy

    include 'lj_force.inc'
    include 'lj_ray.inc'
    include 'lj_pair_helpers.inc'

end module terrace_lj
