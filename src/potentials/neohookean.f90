!> Compressible neo-Hookean elasticity on linear tetrahedra (the talk's strain-energy density,
!> shifted so that W(I) = 0):
!>   W(F) = lambda/2 (ln J)^2 - mu ln J + mu/2 (tr F^T F - 3),   J = det F,
!>   P = dW/dF = mu (F - F^-T) + lambda ln J F^-T,
!> per element F = Ds Dm^-1 with Dm = [X1-X0, X2-X0, X3-X0] (reference, columns) and Ds likewise
!> from the current positions; V = sum_e V0_e W(F_e), V0 = det(Dm)/6. Nodal forces: H = -V0 P Dm^-T,
!> whose columns are the forces on nodes 1..3; node 0 gets minus their sum (so sum f = 0, and the
!> torque vanishes because W depends on F only through F^T F and J). Virial: sum_a x_a.f_a =
!> -V0 P:F = -V0 (mu (|F|^2 - 3) + 3 lambda ln J).
!>
!> Along the ray x + s v (energy stepping): F(s) = F0 + s G, G = Dv Dm^-1, and with A = F0^-1 G,
!> J(s) = J0 p(s), p(s) = 1 + c1 s + c2 s^2 + c3 s^3 (c1 = tr A, c2 = ((tr A)^2 - tr A^2)/2,
!> c3 = det A), tr F^T F (s) = |F0|^2 + 2 s F0:G + s^2 |G|^2, so W, W', W'' have closed forms:
!>   W'  = (lambda L - mu) L' + mu (F0:G + s |G|^2),  L = ln J0 + ln p, L' = p'/p,
!>   W'' = lambda L'^2 + (lambda L - mu) L'' + mu |G|^2,  L'' = p''/p - (p'/p)^2.
!> Where p(s) <= 0 (an element turned inside out) the energy is infinite: the ray returns a huge
!> value there, so the event solver meets a level crossing (a reflection) before it.
!> Each element has its own lambda and mu (a mesh of several materials); setup's scalars are the
!> material of every element not given one.
!>
!> Elements are given by the global ids of their nodes. An element's energy counts on the rank that
!> owns its node of lowest id; its forces are computed on every rank owning one of its nodes, and each
!> owned node sums its elements' forces in element order, so that no force crosses ranks and a node's
!> force has the same bits on any number of ranks. Energies and ray sums are exact sums
!> (terrace_exact_sum), reduced over the ranks here when global_sums is set (a mesh alone; the
!> engine then skips its own sum): with the forces, the run is the same bitwise on 1, 2 or 4 ranks.
!> Kernels (as the pair kernels): per-element data in structures of arrays refreshed by on_rebuild,
!> blocks of nblk elements, the four nodes gathered into contiguous rows, the 3x3 arithmetic
!> branch-free over the block (vectorised; fixed block length, so every element takes the same
!> instructions whatever its place), the nodal forces scattered by owned node after. The ray pass
!> keeps its search-origin coefficients per element while x and v are unchanged, so that the
!> further evaluations of one event's search do only the s-dependent part.
module terrace_neohookean
    use terrace_kinds, only: dp, i8
    use terrace_vec3, only: cross
    use terrace_atoms, only: atoms_t
    use terrace_neighbor_list, only: neighbor_list_t
    use terrace_grow, only: reserve
    use terrace_potential, only: potential_t, halo_ops_t
    use terrace_exact_sum, only: exact_sum_all
    implicit none
    private

    integer, parameter :: nblk = 32                              !< elements per vectorised block
    integer, parameter :: ncoef = 9                              !< ray coefficients per element
    real(dp), parameter, public :: inverted_energy = 1.0e30_dp   !< wall height past an inversion, per V0 (lambda + mu)

    type, extends(potential_t), public :: neohookean_t
        real(dp) :: lambda = 0, mu = 0              !< the default material (elements not given their own)
        integer :: nelem = 0
        integer :: nmaterials = 1                   !< distinct (lambda, mu) pairs among the elements
        real(dp) :: stiffest = 0                    !< largest lambda + 2 mu (the fastest wave, stability)
        real(dp), allocatable :: elam(:), emu(:)    !< (nelem) each element's lambda and mu
        integer(i8), allocatable :: node(:, :)      !< (4, nelem) global node ids
        real(dp), allocatable :: dminv(:, :)        !< (9, nelem) Dm^-1, column major
        real(dp), allocatable :: v0(:)              !< reference volumes
        real(dp) :: reach = 0                       !< largest reference element extent (halo reach hint)
        real(dp) :: min_height = huge(1.0_dp)       !< smallest reference element altitude (stability)
        real(dp) :: density = 0                     !< mass density (for the wave speed; 0: unknown)
        logical :: global_sums = .false.            !< energies and ray sums reduced over the ranks here (exactly)
        ! after on_rebuild: this rank's work list, a structure of arrays by work index k = 1 .. npad
        ! (1 .. nmine: elements whose lowest-id node is owned here; .. nwork: others touching an
        ! owned node; .. npad: padding to whole blocks)
        integer :: nmine = 0, nwork = 0, npad = 0, nlocal = 0
        integer, allocatable :: wl(:)               !< element number (0: padding)
        integer, allocatable :: lidx(:, :)          !< (k, corner) local atom index
        real(dp), allocatable :: rdm(:, :)          !< (k, 1:9) Dm^-1, column major
        real(dp), allocatable :: rv0(:)             !< V0
        real(dp), allocatable :: rlam(:), rmu(:)    !< lambda, mu
        real(dp), allocatable :: wgt(:)             !< 1: its energy counts here; 0: forces only
        real(dp), allocatable :: hf(:, :)           !< (3 (corner - 1) + r, k) nodal forces of the last pass
        real(dp), allocatable :: terms(:, :)        !< (k, 1:4) per-element energy terms, for the exact sums
        integer, allocatable :: first_slot(:)       !< (nlocal + 1) CSR over owned nodes
        integer, allocatable :: slot_k(:), slot_c(:) !< the node's (k, 3 (corner - 1)) in element order
        integer, allocatable :: pos(:)              !< scratch: element -> work index (>0 mine, <0 extra)
        integer, allocatable :: fill(:)             !< scratch
        integer, allocatable :: id_map(:)           !< scratch: global id -> local index (0: not here)
        ! the ray pass's search-origin coefficients (coef(1:ncoef, k)) and the x, v they were made from
        logical :: coef_valid = .false.
        integer :: nall_coef = 0
        real(dp), allocatable :: coef(:, :), xcoef(:, :), vcoef(:, :)
        logical :: missing_node = .false.           !< an element's node was not on this rank
        integer :: first_inverted = 0               !< element with J <= 0 at the last force pass (0: none)
    contains
        procedure :: setup => nh_setup
        procedure :: forces => nh_forces
        procedure :: ray => nh_ray
        procedure :: cutoff => nh_cutoff
        procedure :: describe => nh_describe
        procedure :: halo_reach => nh_halo_reach
        procedure :: needs_pair_list => nh_needs_pair_list
        procedure :: on_rebuild => nh_on_rebuild
        procedure :: energy_density => nh_energy_density
        procedure :: time_unit => nh_time_unit
        procedure :: round_off_scale => nh_round_off_scale
        procedure :: may_become_invalid => nh_may_become_invalid
        procedure :: invalid_state => nh_invalid_state
        procedure :: sums_global => nh_sums_global
    end type neohookean_t

    public :: det3, inv3

contains

    !> Elements from node ids tets(4, ne) and the reference positions xref(3, id) of the nodes, all
    !> of material (lambda, mu), or each of its own (elem_lambda(e), elem_mu(e)) where those are given.
    !> ok = .false. with a message for a degenerate or inverted reference element.
    subroutine nh_setup(self, lambda, mu, tets, xref, ok, msg, elem_lambda, elem_mu)
        class(neohookean_t), intent(inout) :: self
        real(dp), intent(in) :: lambda, mu
        integer(i8), intent(in) :: tets(:, :)
        real(dp), intent(in) :: xref(:, :)       !< (3, max id): reference position of node id
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        real(dp), intent(in), optional :: elem_lambda(:), elem_mu(:)   !< (ne) per-element material
        real(dp) :: dm(3, 3), minv(3, 3), det, size3
        integer :: e, a
        self%lambda = lambda; self%mu = mu
        self%nelem = size(tets, 2)
        allocate (self%node(4, self%nelem), self%dminv(9, self%nelem), self%v0(self%nelem))
        allocate (self%elam(self%nelem), self%emu(self%nelem))
        self%elam = lambda; self%emu = mu
        if (present(elem_lambda) .and. present(elem_mu)) then
            self%elam = elem_lambda; self%emu = elem_mu
        end if
        self%stiffest = maxval(self%elam + 2*self%emu)
        self%nmaterials = count_pairs(self%elam, self%emu)
        self%node = tets
        ok = .true.; msg = ''
        self%reach = 0
        do e = 1, self%nelem
            do a = 1, 3
                dm(:, a) = xref(:, tets(a + 1, e)) - xref(:, tets(1, e))
            end do
            det = det3(dm)
            size3 = max(norm2(dm(:, 1)), norm2(dm(:, 2)), norm2(dm(:, 3)))**3
            if (.not. (det > 1.0e-10_dp*size3)) then
                write (msg, '(a,i0,a,4(1x,i0),a,a,a,es10.3,a)') 'element ', e, ' (nodes', tets(:, e), ') is ', &
                    trim(merge('inverted  ', 'degenerate', det < 0)), ' in the reference mesh (det Dm = ', det, ')'
                ok = .false.
                return
            end if
            minv = inv3(dm, det)
            self%dminv(:, e) = reshape(minv, [9])
            self%v0(e) = det/6
            ! altitudes: 3 V0 / face area, for each face
            self%min_height = min(self%min_height, det/norm2(cross(dm(:, 1), dm(:, 2))), det/norm2(cross(dm(:, 1), dm(:, 3))), &
                                  det/norm2(cross(dm(:, 2), dm(:, 3))), &
                                  det/norm2(cross(dm(:, 2) - dm(:, 1), dm(:, 3) - dm(:, 1))))
            self%reach = max(self%reach, norm2(dm(:, 1)), norm2(dm(:, 2)), norm2(dm(:, 3)), &
                             norm2(dm(:, 2) - dm(:, 1)), norm2(dm(:, 3) - dm(:, 1)), norm2(dm(:, 3) - dm(:, 2)))
        end do
    end subroutine nh_setup

    !> The number of distinct (a(e), b(e)) pairs (each element compared with the first element of
    !> each pair found so far).
    pure integer function count_pairs(a, b) result(n)
        real(dp), intent(in) :: a(:), b(:)
        integer :: e, q
        integer, allocatable :: first(:)
        allocate (first(size(a)))
        n = 0
        do e = 1, size(a)
            do q = 1, n
                if (a(first(q)) == a(e) .and. b(first(q)) == b(e)) exit
            end do
            if (q > n) then
                n = n + 1
                first(n) = e
            end if
        end do
    end function count_pairs

    pure real(dp) function det3(m)
        real(dp), intent(in) :: m(3, 3)
        det3 = m(1, 1)*(m(2, 2)*m(3, 3) - m(2, 3)*m(3, 2)) - m(1, 2)*(m(2, 1)*m(3, 3) - m(2, 3)*m(3, 1)) &
               + m(1, 3)*(m(2, 1)*m(3, 2) - m(2, 2)*m(3, 1))
    end function det3

    !> Inverse of m given its determinant.
    pure function inv3(m, det) result(r)
        real(dp), intent(in) :: m(3, 3), det
        real(dp) :: r(3, 3)
        r(1, 1) = m(2, 2)*m(3, 3) - m(2, 3)*m(3, 2)
        r(1, 2) = m(1, 3)*m(3, 2) - m(1, 2)*m(3, 3)
        r(1, 3) = m(1, 2)*m(2, 3) - m(1, 3)*m(2, 2)
        r(2, 1) = m(2, 3)*m(3, 1) - m(2, 1)*m(3, 3)
        r(2, 2) = m(1, 1)*m(3, 3) - m(1, 3)*m(3, 1)
        r(2, 3) = m(1, 3)*m(2, 1) - m(1, 1)*m(2, 3)
        r(3, 1) = m(2, 1)*m(3, 2) - m(2, 2)*m(3, 1)
        r(3, 2) = m(1, 2)*m(3, 1) - m(1, 1)*m(3, 2)
        r(3, 3) = m(1, 1)*m(2, 2) - m(1, 2)*m(2, 1)
        r = r/det
    end function inv3

    !> W(F) (tests and diagnostics).
    pure real(dp) function nh_energy_density(self, f) result(w)
        class(neohookean_t), intent(in) :: self
        real(dp), intent(in) :: f(3, 3)
        real(dp) :: lnj
        lnj = log(det3(f))
        w = 0.5_dp*self%lambda*lnj**2 - self%mu*lnj + 0.5_dp*self%mu*(sum(f*f) - 3)
    end function nh_energy_density

    !> Map node ids to local indices and lay out this rank's work list: first the elements whose
    !> lowest-id node this rank owns (nmine: their energies count here), then the others that touch
    !> an owned node (their forces on the owned nodes are computed here too, so that no force
    !> crosses ranks), each group in element order, padded to whole blocks of nblk. Per element
    !> (structure of arrays, index k): Dm^-1 (9 columns), V0, the weight of its energy (1 or 0), and
    !> its nodes' local indices. Per owned node: its (element, corner) slots in element order, the
    !> fixed order in which the force pass sums them (the same on any number of ranks).
    subroutine nh_on_rebuild(self, atoms)
        class(neohookean_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        integer :: nlocal
        nlocal = atoms%nlocal
        call map_node_ids(self, atoms)
        call classify_elements(self, nlocal)
        call fill_work_list(self)
        call fill_node_slots(self, nlocal)
        self%nlocal = nlocal
        self%coef_valid = .false.
    end subroutine nh_on_rebuild

    !> id_map(id): the local index of node id (owned atoms win over a periodic ghost image of the
    !> same id), 0 where this rank holds no copy.
    subroutine map_node_ids(self, atoms)
        class(neohookean_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        integer :: i, nall
        integer(i8) :: maxid
        nall = atoms%nall()
        maxid = maxval(self%node)
        call reserve(self%id_map, int(maxid), exact=.true.)
        self%id_map = 0
        ! owned atoms last, so that an owned copy wins over a periodic ghost image of the same id
        do i = nall, 1, -1
            if (atoms%id(i) >= 1 .and. atoms%id(i) <= maxid) self%id_map(atoms%id(i)) = i
        end do
    end subroutine map_node_ids

    !> pos(e) > 0: element e is mine (its lowest-id node is owned), its place among mine; pos(e) < 0:
    !> it touches an owned node only, minus its place among those; 0: neither. Sets nmine, nwork,
    !> npad.
    subroutine classify_elements(self, nlocal)
        class(neohookean_t), intent(inout) :: self
        integer, intent(in) :: nlocal
        integer :: i, e, a, n, low, nextra
        logical :: touches
        if (.not. allocated(self%pos)) allocate (self%pos(self%nelem))
        n = 0; nextra = 0
        do e = 1, self%nelem
            self%pos(e) = 0
            low = minloc(self%node(:, e), 1)
            i = self%id_map(self%node(low, e))
            if (i >= 1 .and. i <= nlocal) then
                n = n + 1
                self%pos(e) = n
                cycle
            end if
            touches = .false.
            do a = 1, 4
                i = self%id_map(self%node(a, e))
                if (i >= 1 .and. i <= nlocal) touches = .true.
            end do
            if (touches) then
                nextra = nextra + 1
                self%pos(e) = -nextra
            end if
        end do
        self%nmine = n
        self%nwork = n + nextra
        self%npad = nblk*((self%nwork + nblk - 1)/nblk)
    end subroutine classify_elements

    !> The work list as a structure of arrays (element, local node indices, Dm^-1, V0, energy
    !> weight), mine first, padded to whole blocks of nblk.
    subroutine fill_work_list(self)
        class(neohookean_t), intent(inout) :: self
        integer :: i, e, a, n, k, c
        n = self%nmine
        if (allocated(self%wl)) then
            if (size(self%wl) < self%npad) deallocate (self%wl, self%lidx, self%rdm, self%rv0, self%wgt, self%hf, self%terms, &
                                                       self%rlam, self%rmu)
        end if
        if (.not. allocated(self%wl)) then
            k = max(self%npad, nblk)
            allocate (self%wl(k), self%lidx(k, 4), self%rdm(k, 9), self%rv0(k), self%wgt(k), self%hf(12, k), self%terms(k, 4), &
                      self%rlam(k), self%rmu(k))
        end if
        self%missing_node = .false.
        do e = 1, self%nelem
            if (self%pos(e) == 0) cycle
            k = self%pos(e)
            if (k < 0) k = n - k
            self%wl(k) = e
            do a = 1, 4
                i = self%id_map(self%node(a, e))
                if (i == 0) then
                    self%missing_node = .true.
                    i = 1
                end if
                self%lidx(k, a) = i
            end do
            do c = 1, 9
                self%rdm(k, c) = self%dminv(c, e)
            end do
            self%rv0(k) = self%v0(e)
            self%rlam(k) = self%elam(e); self%rmu(k) = self%emu(e)
            self%wgt(k) = merge(1.0_dp, 0.0_dp, k <= n)
        end do
        ! padding (only when there is work): copies of the first element, weight 0, never scattered
        do k = self%nwork + 1, self%npad
            self%wl(k) = 0
            self%lidx(k, :) = self%lidx(1, :)
            self%rdm(k, :) = self%rdm(1, :)
            self%rv0(k) = 0
            self%rlam(k) = self%rlam(1); self%rmu(k) = self%rmu(1)
            self%wgt(k) = 0
        end do
    end subroutine fill_work_list

    !> Per owned node, its (work item, corner) slots in element order (CSR: first_slot, slot_k,
    !> slot_c), the fixed order in which the force pass sums them.
    subroutine fill_node_slots(self, nlocal)
        class(neohookean_t), intent(inout) :: self
        integer, intent(in) :: nlocal
        integer :: i, e, a, k
        call reserve(self%first_slot, nlocal + 1, exact=.true.)
        self%first_slot(1:nlocal + 1) = 0
        do k = 1, self%nwork
            do a = 1, 4
                i = self%lidx(k, a)
                if (i <= nlocal) self%first_slot(i + 1) = self%first_slot(i + 1) + 1
            end do
        end do
        self%first_slot(1) = 1
        do i = 1, nlocal
            self%first_slot(i + 1) = self%first_slot(i) + self%first_slot(i + 1)
        end do
        call reserve(self%slot_k, self%first_slot(nlocal + 1) - 1, minimum=1, exact=.true.)
        call reserve(self%slot_c, self%first_slot(nlocal + 1) - 1, minimum=1, exact=.true.)
        ! fill in element order (pos maps element numbers to work indices)
        call reserve(self%fill, nlocal, minimum=1, exact=.true.)
        do i = 1, nlocal
            self%fill(i) = self%first_slot(i)
        end do
        do e = 1, self%nelem
            if (self%pos(e) == 0) cycle
            k = self%pos(e)
            if (k < 0) k = self%nmine - k
            do a = 1, 4
                i = self%lidx(k, a)
                if (i > nlocal) cycle
                self%slot_k(self%fill(i)) = k
                self%slot_c(self%fill(i)) = 3*(a - 1)
                self%fill(i) = self%fill(i) + 1
            end do
        end do
    end subroutine fill_node_slots

    !> Forces, and the energy and virial (always computed: they cost nothing extra here). Blocks of
    !> nblk elements: gather the edge vectors into contiguous rows, the arithmetic branch-free over
    !> the block (vectorised), the 12 nodal forces per element into hf; then every owned node sums
    !> its slots in element order. The energy and virial are exact sums (terrace_exact_sum), global
    !> when global_sums is set.
    subroutine nh_forces(self, atoms, list, halo, want_energy, energy, virial)
        class(neohookean_t), intent(inout) :: self
        include 'potential_forces_args.inc'
        real(dp) :: ds(nblk, 9), tot(2)
        integer :: b, j, k0, i, s, c
        real(dp) :: bad(nblk), acc(3)
        self%first_inverted = 0
        do b = 1, self%npad/nblk
            k0 = (b - 1)*nblk
            call gather_edges(atoms%x, self%lidx, k0, ds)
            call force_block(k0, ds, self%rdm, self%rv0, self%wgt, self%rlam, self%rmu, self%hf, self%terms, bad)
            if (self%first_inverted == 0 .and. any(bad > 0)) then
                do j = 1, nblk
                    if (bad(j) > 0 .and. k0 + j <= self%nwork) then
                        self%first_inverted = self%wl(k0 + j)
                        exit
                    end if
                end do
            end if
        end do
        ! scatter: owned nodes only, each its slots in element order
        do i = 1, self%nlocal
            acc = 0
            do s = self%first_slot(i), self%first_slot(i + 1) - 1
                do c = 1, 3
                    acc(c) = acc(c) + self%hf(self%slot_c(s) + c, self%slot_k(s))
                end do
            end do
            atoms%f(:, i) = atoms%f(:, i) + acc
        end do
        energy = 0; virial = 0
        if (.not. want_energy) return
        call exact_sum_all(self%terms(:, 1:2), self%npad, int(self%nelem, i8), tot, self%global_sums)
        energy = tot(1); virial = tot(2)
    end subroutine nh_forces

    !> Edge vectors of the elements k0+1 .. k0+nblk: rows (r + 3 (a - 1)) = y(r, node a+1) - y(r, node 1).
    subroutine gather_edges(y, lidx, k0, d)
        real(dp), intent(in) :: y(:, :)
        integer, intent(in) :: lidx(:, :), k0
        real(dp), intent(out) :: d(nblk, 9)
        integer :: j, a, r, l1, la
        do j = 1, nblk
            l1 = lidx(k0 + j, 1)
            do a = 1, 3
                la = lidx(k0 + j, a + 1)
                do r = 1, 3
                    d(j, r + 3*(a - 1)) = y(r, la) - y(r, l1)
                end do
            end do
        end do
    end subroutine gather_edges

    !> One block of the force pass: F = Ds Dm^-1, J, F^-T = cof(F)/J, P = mu (F - F^-T) + lambda ln J F^-T,
    !> H = -V0 P Dm^-T (nodes 2..4; node 1 gets minus their sum), and the weighted energy and virial.
    !> (The nodal forces go to hf(12, k): with hf(k, 12), twelve separate store streams, GCC 12 does
    !> not vectorise the loop.)
    !> An inverted element (J <= 0) gets no force and no energy and is flagged.
    subroutine force_block(k0, ds, rdm, rv0, wgt, rlam, rmu, hf, terms, bad)
        integer, intent(in) :: k0
        real(dp), intent(in) :: ds(nblk, 9)
        real(dp), intent(in), contiguous :: rdm(:, :), rv0(:), wgt(:), rlam(:), rmu(:)
        real(dp), intent(inout), contiguous :: hf(:, :), terms(:, :)
        real(dp), intent(out) :: bad(nblk)       !< 1: inverted
        integer :: j, k
        logical :: okj
        real(dp) :: f11, f21, f31, f12, f22, f32, f13, f23, f33, c11, c21, c31, c12, c22, c32, c13, c23, c33, &
                    jac, js, rj, lnj, v0, p11, p21, p31, p12, p22, p32, p13, p23, p33, h11, h21, h31, h12, h22, h32, &
                    h13, h23, h33, ff, w, m11, m21, m31, m12, m22, m32, m13, m23, m33, lambda, mu
        do j = 1, nblk
            k = k0 + j
            include 'neohookean_f.inc'
            lambda = rlam(k); mu = rmu(k)
            ! cofactors: F^-T = C / J
            c11 = f22*f33 - f23*f32; c12 = f23*f31 - f21*f33; c13 = f21*f32 - f22*f31
            c21 = f13*f32 - f12*f33; c22 = f11*f33 - f13*f31; c23 = f12*f31 - f11*f32
            c31 = f12*f23 - f13*f22; c32 = f13*f21 - f11*f23; c33 = f11*f22 - f12*f21
            jac = f11*c11 + f12*c12 + f13*c13
            ! branch-free: the operands of every merge are plain values computed before it
            v0 = rv0(k)
            okj = jac > 0
            js = merge(jac, 1.0_dp, okj)
            v0 = merge(v0, 0.0_dp, okj)
            bad(j) = merge(0.0_dp, 1.0_dp, okj)
            rj = 1/js
            lnj = log(js)
            ! P = mu F + (lambda ln J - mu) F^-T
            w = (lambda*lnj - mu)*rj
            p11 = mu*f11 + w*c11; p21 = mu*f21 + w*c21; p31 = mu*f31 + w*c31
            p12 = mu*f12 + w*c12; p22 = mu*f22 + w*c22; p32 = mu*f32 + w*c32
            p13 = mu*f13 + w*c13; p23 = mu*f23 + w*c23; p33 = mu*f33 + w*c33
            ! H = -V0 P Dm^-T: column a = -V0 sum_c P(:, c) Dm^-1(a, c)
            h11 = -v0*(p11*m11 + p12*m12 + p13*m13)
            h21 = -v0*(p21*m11 + p22*m12 + p23*m13)
            h31 = -v0*(p31*m11 + p32*m12 + p33*m13)
            h12 = -v0*(p11*m21 + p12*m22 + p13*m23)
            h22 = -v0*(p21*m21 + p22*m22 + p23*m23)
            h32 = -v0*(p31*m21 + p32*m22 + p33*m23)
            h13 = -v0*(p11*m31 + p12*m32 + p13*m33)
            h23 = -v0*(p21*m31 + p22*m32 + p23*m33)
            h33 = -v0*(p31*m31 + p32*m32 + p33*m33)
            hf(1, k) = -(h11 + h12 + h13); hf(2, k) = -(h21 + h22 + h23); hf(3, k) = -(h31 + h32 + h33)
            hf(4, k) = h11; hf(5, k) = h21; hf(6, k) = h31
            hf(7, k) = h12; hf(8, k) = h22; hf(9, k) = h32
            hf(10, k) = h13; hf(11, k) = h23; hf(12, k) = h33
            ff = f11*f11 + f21*f21 + f31*f31 + f12*f12 + f22*f22 + f32*f32 + f13*f13 + f23*f23 + f33*f33
            v0 = wgt(k)*v0
            terms(k, 1) = v0*(0.5_dp*lambda*lnj*lnj - mu*lnj + 0.5_dp*mu*(ff - 3))
            terms(k, 2) = -v0*(mu*(ff - 3) + 3*lambda*lnj)
        end do
    end subroutine force_block

    !> (V, V', V'', W) of this rank's elements at x + s v (exact sums, global when global_sums is set).
    !> Everything but the cubic p(s), its log and tr F^T F (s) depends only on the search origin x, v:
    !> those per-element coefficients are kept (coef) while x and v (owned and ghosts) are bitwise
    !> those of the last pass, so the further evaluations of one event's search cost only the
    !> s-dependent part. on_rebuild drops them.
    subroutine nh_ray(self, atoms, list, s, out)
        class(neohookean_t), intent(inout) :: self
        include 'potential_ray_args.inc'
        real(dp) :: ds(nblk, 9), dv(nblk, 9)
        integer :: b, k0, nb, nmine_pad, nall
        logical :: same
        nmine_pad = nblk*((self%nmine + nblk - 1)/nblk)
        nb = nmine_pad/nblk
        nall = atoms%nall()
        same = self%coef_valid .and. nall == self%nall_coef
        if (same) same = all(atoms%x(:, 1:nall) == self%xcoef(:, 1:nall))
        if (same) same = all(atoms%v(:, 1:nall) == self%vcoef(:, 1:nall))
        if (.not. same) then
            if (allocated(self%xcoef)) then
                if (size(self%xcoef, 2) < nall) deallocate (self%xcoef, self%vcoef)
            end if
            if (.not. allocated(self%xcoef)) allocate (self%xcoef(3, max(nall, 1)), self%vcoef(3, max(nall, 1)))
            if (allocated(self%coef)) then
                if (size(self%coef, 2) < nmine_pad) deallocate (self%coef)
            end if
            if (.not. allocated(self%coef)) allocate (self%coef(ncoef, max(nmine_pad, nblk)))
            do b = 1, nb
                k0 = (b - 1)*nblk
                call gather_edges(atoms%x, self%lidx, k0, ds)
                call gather_edges(atoms%v, self%lidx, k0, dv)
                call ray_coef_block(k0, ds, dv, self%rdm, self%rv0, self%wgt, self%coef)
            end do
            self%xcoef(:, 1:nall) = atoms%x(:, 1:nall)
            self%vcoef(:, 1:nall) = atoms%v(:, 1:nall)
            self%nall_coef = nall
            self%coef_valid = .true.
        end if
        do b = 1, nb
            call ray_eval_block((b - 1)*nblk, s, self%coef, self%rlam, self%rmu, self%terms)
        end do
        call exact_sum_all(self%terms, nmine_pad, int(self%nelem, i8), out, self%global_sums)
    end subroutine nh_ray

    !> The search origin's part of one block of the ray pass: F0 = Ds Dm^-1, G = Dv Dm^-1,
    !> A = F0^-1 G = adj(F0) G / J0, and p(s) = det(I + s A) = 1 + c1 s + c2 s^2 + c3 s^3:
    !> coef(:, k) = (c1, c2, c3, ln J0, |F0|^2, F0:G, |G|^2, weighted V0, 1 if J0 <= 0).
    subroutine ray_coef_block(k0, ds, dv, rdm, rv0, wgt, coef)
        integer, intent(in) :: k0
        real(dp), intent(in) :: ds(nblk, 9), dv(nblk, 9)
        real(dp), intent(in), contiguous :: rdm(:, :), rv0(:), wgt(:)
        real(dp), intent(inout), contiguous :: coef(:, :)
        integer :: j, k
        real(dp) :: f11, f21, f31, f12, f22, f32, f13, f23, f33, g11, g21, g31, g12, g22, g32, g13, g23, g33, &
                    a11, a21, a31, a12, a22, a32, a13, a23, a33, c11, c21, c31, c12, c22, c32, c13, c23, c33, &
                    m11, m21, m31, m12, m22, m32, m13, m23, m33, j0, js, rj, q1, q2, q3, t0, fg, gg
        logical :: inv0
        do j = 1, nblk
            k = k0 + j
            include 'neohookean_f.inc'
            g11 = dv(j, 1)*m11 + dv(j, 4)*m21 + dv(j, 7)*m31
            g21 = dv(j, 2)*m11 + dv(j, 5)*m21 + dv(j, 8)*m31
            g31 = dv(j, 3)*m11 + dv(j, 6)*m21 + dv(j, 9)*m31
            g12 = dv(j, 1)*m12 + dv(j, 4)*m22 + dv(j, 7)*m32
            g22 = dv(j, 2)*m12 + dv(j, 5)*m22 + dv(j, 8)*m32
            g32 = dv(j, 3)*m12 + dv(j, 6)*m22 + dv(j, 9)*m32
            g13 = dv(j, 1)*m13 + dv(j, 4)*m23 + dv(j, 7)*m33
            g23 = dv(j, 2)*m13 + dv(j, 5)*m23 + dv(j, 8)*m33
            g33 = dv(j, 3)*m13 + dv(j, 6)*m23 + dv(j, 9)*m33
            ! cofactors of F0 (adj(F0) = C^T)
            c11 = f22*f33 - f23*f32; c12 = f23*f31 - f21*f33; c13 = f21*f32 - f22*f31
            c21 = f13*f32 - f12*f33; c22 = f11*f33 - f13*f31; c23 = f12*f31 - f11*f32
            c31 = f12*f23 - f13*f22; c32 = f13*f21 - f11*f23; c33 = f11*f22 - f12*f21
            j0 = f11*c11 + f12*c12 + f13*c13
            inv0 = .not. (j0 > 0)
            js = merge(1.0_dp, j0, inv0)
            rj = 1/js
            ! A = adj(F0) G / J0, adj(F0)(r, c) = C(c, r)
            a11 = (c11*g11 + c21*g21 + c31*g31)*rj
            a21 = (c12*g11 + c22*g21 + c32*g31)*rj
            a31 = (c13*g11 + c23*g21 + c33*g31)*rj
            a12 = (c11*g12 + c21*g22 + c31*g32)*rj
            a22 = (c12*g12 + c22*g22 + c32*g32)*rj
            a32 = (c13*g12 + c23*g22 + c33*g32)*rj
            a13 = (c11*g13 + c21*g23 + c31*g33)*rj
            a23 = (c12*g13 + c22*g23 + c32*g33)*rj
            a33 = (c13*g13 + c23*g23 + c33*g33)*rj
            q1 = a11 + a22 + a33
            q2 = 0.5_dp*(q1*q1 - (a11*a11 + a22*a22 + a33*a33 + 2*(a12*a21 + a13*a31 + a23*a32)))
            q3 = a11*(a22*a33 - a23*a32) - a12*(a21*a33 - a23*a31) + a13*(a21*a32 - a22*a31)
            t0 = f11*f11 + f21*f21 + f31*f31 + f12*f12 + f22*f22 + f32*f32 + f13*f13 + f23*f23 + f33*f33
            fg = f11*g11 + f21*g21 + f31*g31 + f12*g12 + f22*g22 + f32*g32 + f13*g13 + f23*g23 + f33*g33
            gg = g11*g11 + g21*g21 + g31*g31 + g12*g12 + g22*g22 + g32*g32 + g13*g13 + g23*g23 + g33*g33
            coef(1, k) = q1; coef(2, k) = q2; coef(3, k) = q3
            coef(4, k) = log(js)
            coef(5, k) = t0; coef(6, k) = fg; coef(7, k) = gg
            coef(8, k) = wgt(k)*rv0(k)
            coef(9, k) = merge(1.0_dp, 0.0_dp, inv0)
        end do
    end subroutine ray_coef_block

    !> The s-dependent part of one block of the ray pass, from coef: p(s), p', p'', ln J = ln J0 +
    !> ln p, W, W', W'' and the virial term at s. Past an inversion (J0 <= 0, or p(s) <= 0) the wall
    !> energy and no derivatives. Each element's lambda and mu from the work list (rlam, rmu).
    subroutine ray_eval_block(k0, s, coef, rlam, rmu, terms)
        integer, intent(in) :: k0
        real(dp), intent(in) :: s
        real(dp), intent(in), contiguous :: coef(:, :), rlam(:), rmu(:)
        real(dp), intent(inout), contiguous :: terms(:, :)
        integer :: j, k
        real(dp) :: q1, q2, q3, pp, ps, p1, p2, lnj, l1, l2, t0, fg, gg, trf, w, w1, w2, v0, wall, lm, vir, lambda, mu
        real(dp) :: cb(nblk, ncoef)
        logical :: inv0, ok, okp
        integer :: c
        ! the block's coefficients into contiguous rows
        do j = 1, nblk
            do c = 1, ncoef
                cb(j, c) = coef(c, k0 + j)
            end do
        end do
        do j = 1, nblk
            k = k0 + j
            q1 = cb(j, 1); q2 = cb(j, 2); q3 = cb(j, 3)
            t0 = cb(j, 5); fg = cb(j, 6); gg = cb(j, 7); v0 = cb(j, 8)
            inv0 = cb(j, 9) > 0
            lambda = rlam(k); mu = rmu(k)
            pp = 1 + s*(q1 + s*(q2 + s*q3))
            okp = pp > 0
            ok = okp .and. .not. inv0
            ps = merge(pp, 1.0_dp, ok)
            p1 = q1 + s*(2*q2 + 3*s*q3)
            p2 = 2*q2 + 6*s*q3
            lnj = cb(j, 4) + log(ps)
            l1 = p1/ps
            l2 = p2/ps - l1*l1
            trf = t0 + 2*s*fg + s*s*gg
            lm = lambda*lnj - mu
            w = 0.5_dp*lambda*lnj*lnj - mu*lnj + 0.5_dp*mu*(trf - 3)
            w1 = lm*l1 + mu*(fg + s*gg)
            w2 = lambda*l1*l1 + lm*l2 + mu*gg
            ! an energy wall the search cannot pass: at J0 <= 0, and beyond the inversion along the ray
            ! (branch-free: the operands of every merge are plain values computed before it)
            wall = merge(1.0_dp, 1 + abs(s), inv0)
            wall = inverted_energy*v0*(lambda + mu)*wall
            w = v0*w; w1 = v0*w1; w2 = v0*w2
            vir = -v0*(mu*(trf - 3) + 3*lambda*lnj)
            terms(k, 1) = merge(w, wall, ok)
            terms(k, 2) = merge(w1, 0.0_dp, ok)
            terms(k, 3) = merge(w2, 0.0_dp, ok)
            terms(k, 4) = merge(vir, 0.0_dp, ok)
        end do
    end subroutine ray_eval_block

    !> The engine prints 0.005 tau as a stable velocity-Verlet step: tau = 100 l_min / c_d makes that
    !> l_min / (2 c_d), half the element's dilatational transit time (c_d = sqrt((lambda + 2 mu)/rho)),
    !> with the smallest element and the stiffest material (a bound when they are different elements).
    pure subroutine nh_time_unit(self, mass, mvv2e, tau, words)
        class(neohookean_t), intent(in) :: self
        real(dp), intent(in) :: mass, mvv2e
        real(dp), intent(out) :: tau
        character(len=:), allocatable, intent(out) :: words
        tau = 0
        if (self%density > 0) tau = 100*self%min_height/sqrt(self%stiffest/self%density)
        words = 'half the smallest element''s wave transit'
    end subroutine nh_time_unit


    !> sum_e V0_e (lambda_e + 3 mu_e), over every element of the mesh: each element's W is a sum of
    !> terms of that size (mu/2 |F|^2 with |F|^2 near 3, mu ln J and lambda ln J with J near 1) that
    !> cancel near the rest shape, so its energy carries a round-off of a few eps of it, however small
    !> W is (lambda = 2.7e8 Pa, mu = 3e7 Pa on 1.2e-4 m^3: 4.2e4 J per element).
    pure real(dp) function nh_round_off_scale(self) result(e)
        class(neohookean_t), intent(in) :: self
        e = 0
        if (allocated(self%v0)) e = sum(self%v0*(self%elam + 3*self%emu))
    end function nh_round_off_scale

    pure logical function nh_may_become_invalid(self)
        class(neohookean_t), intent(in) :: self
        nh_may_become_invalid = .true.
    end function nh_may_become_invalid

    !> An element turned inside out (J <= 0) at the last force pass, or one whose nodes were not all
    !> on this rank (the halo was too short).
    logical function nh_invalid_state(self, text) result(bad)
        class(neohookean_t), intent(in) :: self
        character(len=*), intent(out) :: text
        bad = .false.
        text = ''
        if (self%first_inverted > 0) then
            write (text, '(a,i0,a,4(1x,i0),a)') 'element ', self%first_inverted, ' (nodes', &
                self%node(:, self%first_inverted), ') turned inside out (J <= 0): the time step (&integrator dt) is too large for '// &
                'this mesh and material (terrace --check prints the stable step), or the deformation is beyond the mesh'
            bad = .true.
        else if (self%missing_node) then
            text = 'an element''s node is not among this rank''s atoms (the halo is too short for the deformation)'
            bad = .true.
        end if
    end function nh_invalid_state

    !> Energies and ray sums already global (global_sums): the engine must not sum them again.
    pure logical function nh_sums_global(self)
        class(neohookean_t), intent(in) :: self
        nh_sums_global = self%global_sums
    end function nh_sums_global

    !> No pair interactions.
    pure real(dp) function nh_cutoff(self)
        class(neohookean_t), intent(in) :: self
        nh_cutoff = 0
    end function nh_cutoff

    !> Ghosts must cover every element of an owned lowest-id node: its largest reference extent,
    !> doubled for the stretch a moving body reaches.
    pure real(dp) function nh_halo_reach(self)
        class(neohookean_t), intent(in) :: self
        nh_halo_reach = 2*self%reach
    end function nh_halo_reach

    pure logical function nh_needs_pair_list(self)
        class(neohookean_t), intent(in) :: self
        nh_needs_pair_list = .false.
    end function nh_needs_pair_list

    function nh_describe(self) result(text)
        class(neohookean_t), intent(in) :: self
        character(len=:), allocatable :: text
        character(len=200) :: s
        if (self%nmaterials > 1) then
            write (s, '(a,i0,a,i0,a,es11.4,a,es11.4,a)') 'neohookean, ', self%nelem, ' tetrahedra of ', self%nmaterials, &
                ' materials (lambda + 2 mu from ', minval(self%elam + 2*self%emu), ' to ', self%stiffest, &
                '); no pair list, no density pass'
        else
            write (s, '(a,i0,a,es11.4,a,es11.4,a)') 'neohookean, ', self%nelem, ' tetrahedra, lambda = ', self%lambda, &
                ', mu = ', self%mu, '; no pair list, no density pass'
        end if
        text = trim(s)
    end function nh_describe

end module terrace_neohookean
