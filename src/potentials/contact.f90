!> Frictionless contact between the bodies of a mesh: a pair barrier between boundary nodes of
!> different bodies,
!>   V = sum over pairs (i, j), body(i) /= body(j), r_ij < d0:  k/2 (d0 - r_ij)^2,
!> continuous with a continuous gradient (the force k (d0 - r) falls to 0 at r = d0). The forces are
!> central, equal and opposite: linear and angular momentum are conserved exactly.
!> Boundary nodes: the nodes of the faces that belong to exactly one tetrahedron. Candidates: the
!> engine's half neighbour list (cutoff d0 + skin), filtered once per list build into the pairs of
!> boundary nodes of different bodies (nodes inside a body and pairs within one body are skipped
!> there and never looked at again until the next build).
!>
!> Along the ray x + s v: with dx = x_i - x_j, dv = v_i - v_j, r(s)^2 = |dx|^2 + 2 s dx.dv + s^2 |dv|^2,
!>   r' = (dx.dv + s |dv|^2)/r,  r'' = (|dv|^2 - r'^2)/r,
!>   V' = -k (d0 - r) r',  V'' = k r'^2 - k (d0 - r) r'',  W = k (d0 - r) r   (virial x.f).
!>
!> Defaults (doc/contact.md): d0 = the mean boundary edge length h_b (a node must meet the nodes of
!> the other body before it can pass between them: d0 above the boundary triangles' circumradius,
!> about 0.6 h_b); k = E d0 (a surface node's share of a layer of the material one element thick),
!> E Young's modulus of the elements' Lame constants.
module terrace_contact
    use terrace_kinds, only: dp, i8
    use terrace_atoms, only: atoms_t
    use terrace_neighbor_list, only: neighbor_list_t
    use terrace_potential, only: potential_t, halo_ops_t
    implicit none
    private

    type, extends(potential_t), public :: contact_t
        real(dp) :: k = 0, d0 = 0
        integer :: nbodies = 0
        integer :: nboundary = 0                    !< boundary nodes (all bodies)
        integer, allocatable :: tag_of_id(:)        !< body of a boundary node, 0 for an interior node
        real(dp) :: spacing = 0                     !< mean boundary edge length
        real(dp) :: min_body_extent = 0             !< smallest bounding-box edge of any body
        real(dp) :: min_mass = 0                    !< lightest boundary node (lumped), for the time scale
        ! per local atom (after on_rebuild) and the candidate pairs (after the first pass past a build)
        integer, allocatable :: tag(:)
        logical :: stale = .true.
        integer :: npair = 0
        integer, allocatable :: pi(:), pj(:)
    contains
        procedure :: setup => ct_setup
        procedure :: check_start => ct_check_start
        procedure :: forces => ct_forces
        procedure :: ray => ct_ray
        procedure :: cutoff => ct_cutoff
        procedure :: describe => ct_describe
        procedure :: on_rebuild => ct_on_rebuild
        procedure :: time_scale => ct_time_scale
        procedure :: preferred_skin => ct_preferred_skin
    end type contact_t

    public :: boundary_nodes

contains

    !> Boundary faces of a mesh of tetrahedra tets(4, ne) over node ids 1..nnode: the faces that
    !> belong to exactly one tetrahedron, as faces(3, nf) of node ids; is_boundary marks their nodes.
    subroutine boundary_nodes(tets, nnode, is_boundary, faces)
        integer(i8), intent(in) :: tets(:, :)
        integer, intent(in) :: nnode
        logical, intent(out) :: is_boundary(nnode)
        integer, allocatable, intent(out) :: faces(:, :)
        integer, parameter :: fl(3, 4) = reshape([2, 3, 4, 1, 3, 4, 1, 2, 4, 1, 2, 3], [3, 4])
        integer, allocatable :: start(:), fb(:), fc(:), fill(:), cnt(:)
        integer :: ne, e, q, a, lo, m, p, nf, pass
        integer :: s(3)
        ne = size(tets, 2)
        ! faces bucketed by their lowest node id: (b, c) the two others, sorted
        allocate (start(nnode + 1), fill(nnode), fb(4*ne), fc(4*ne), cnt(4*ne))
        start = 0
        do e = 1, ne
            do q = 1, 4
                lo = int(minval(tets(fl(:, q), e)))
                start(lo + 1) = start(lo + 1) + 1
            end do
        end do
        start(1) = 1
        do a = 1, nnode
            start(a + 1) = start(a + 1) + start(a)
        end do
        fill = start(1:nnode)
        do e = 1, ne
            do q = 1, 4
                s = sorted3(int(tets(fl(:, q), e)))
                fb(fill(s(1))) = s(2); fc(fill(s(1))) = s(3)
                fill(s(1)) = fill(s(1)) + 1
            end do
        end do
        cnt = 0
        do a = 1, nnode
            do m = start(a), start(a + 1) - 1
                do p = start(a), start(a + 1) - 1
                    if (fb(p) == fb(m) .and. fc(p) == fc(m)) cnt(m) = cnt(m) + 1
                end do
            end do
        end do
        is_boundary = .false.
        do pass = 1, 2
            nf = 0
            do a = 1, nnode
                do m = start(a), start(a + 1) - 1
                    if (cnt(m) /= 1) cycle
                    nf = nf + 1
                    if (pass == 2) then
                        faces(:, nf) = [a, fb(m), fc(m)]
                        is_boundary(a) = .true.; is_boundary(fb(m)) = .true.; is_boundary(fc(m)) = .true.
                    end if
                end do
            end do
            if (pass == 1) allocate (faces(3, nf))
        end do
    contains
        pure function sorted3(t) result(o)
            integer, intent(in) :: t(3)
            integer :: o(3)
            o = [minval(t), sum(t) - minval(t) - maxval(t), maxval(t)]
        end function sorted3
    end subroutine boundary_nodes

    !> The term for a mesh: tets(4, ne) by node id, body(ne) the physical volume of each
    !> tetrahedron, xref(3, id) reference positions, density (for the lumped masses in the time
    !> scale). k <= 0 or d0 <= 0: the defaults (E d0 and the mean boundary edge); E the elements'
    !> Young's modulus. ok = .false. with a message when fewer than two bodies hold boundary nodes.
    subroutine ct_setup(self, k, d0, youngs, tets, body, xref, node_mass)
        class(contact_t), intent(inout) :: self
        real(dp), intent(in) :: k, d0, youngs
        real(dp), intent(in) :: node_mass(:)      !< lumped node masses by id (the scene's)
        integer(i8), intent(in) :: tets(:, :)
        integer, intent(in) :: body(:)
        real(dp), intent(in) :: xref(:, :)
        logical, allocatable :: bnd(:)
        real(dp), allocatable :: lo(:, :), hi(:, :)
        integer, allocatable :: node_body(:), faces(:, :)
        integer :: nnode, e, a, q, nb
        real(dp) :: sum_edge
        integer(i8) :: n_edge
        nnode = size(xref, 2)
        allocate (bnd(nnode), node_body(nnode))
        call boundary_nodes(tets, nnode, bnd, faces)
        nb = maxval(body)
        node_body = 0
        do e = 1, size(tets, 2)
            do a = 1, 4
                node_body(tets(a, e)) = body(e)
            end do
        end do
        sum_edge = 0
        do q = 1, size(faces, 2)
            do a = 1, 3
                sum_edge = sum_edge + norm2(xref(:, faces(a, q)) - xref(:, faces(mod(a, 3) + 1, q)))
            end do
        end do
        n_edge = 3*size(faces, 2)
        self%spacing = sum_edge/max(n_edge, 1_i8)
        allocate (self%tag_of_id(nnode))
        self%tag_of_id = merge(node_body, 0, bnd)
        self%nboundary = count(bnd)
        self%nbodies = 0
        allocate (lo(3, nb), hi(3, nb))
        call body_boxes(xref, node_body, lo, hi)
        self%min_body_extent = huge(1.0_dp)
        do a = 1, nb
            if (count(self%tag_of_id == a) == 0) cycle
            self%nbodies = self%nbodies + 1
            self%min_body_extent = min(self%min_body_extent, minval(hi(:, a) - lo(:, a)))
        end do
        self%min_mass = minval(node_mass(1:nnode), mask=bnd)
        self%d0 = d0
        if (.not. (d0 > 0)) self%d0 = self%spacing
        self%k = k
        if (.not. (k > 0)) self%k = youngs*self%d0
    end subroutine ct_setup

    !> Refuse a start where two bodies already touch or overlap: boundary nodes of different bodies
    !> closer than d0, or a node of one body inside a tetrahedron of another. x(3, id): the starting
    !> positions. ok = .false. with a message naming both bodies.
    subroutine ct_check_start(self, x, tets, body, ok, msg)
        class(contact_t), intent(in) :: self
        real(dp), intent(in) :: x(:, :)
        integer(i8), intent(in) :: tets(:, :)
        integer, intent(in) :: body(:)
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        integer, allocatable :: node_body(:)
        real(dp), allocatable :: lo(:, :), hi(:, :)
        real(dp) :: r, tlo(3), thi(3), lam(4)
        integer :: nb, i, j, e, bi, bj, n
        ok = .true.; msg = ''
        n = size(x, 2)
        nb = maxval(body)
        allocate (node_body(n), lo(3, nb), hi(3, nb))
        node_body = 0
        do e = 1, size(tets, 2)
            node_body(tets(:, e)) = body(e)
        end do
        call body_boxes(x, node_body, lo, hi)
        ! a node of one body inside a tetrahedron of another (bounding boxes first)
        do e = 1, size(tets, 2)
            bj = body(e)
            tlo = min(min(x(:, tets(1, e)), x(:, tets(2, e))), min(x(:, tets(3, e)), x(:, tets(4, e))))
            thi = max(max(x(:, tets(1, e)), x(:, tets(2, e))), max(x(:, tets(3, e)), x(:, tets(4, e))))
            do bi = 1, nb
                if (bi == bj) cycle
                if (any(lo(:, bi) > thi) .or. any(hi(:, bi) < tlo)) cycle
                do i = 1, n
                    if (node_body(i) /= bi) cycle
                    if (any(x(:, i) < tlo) .or. any(x(:, i) > thi)) cycle
                    lam = barycentric(x(:, i), x(:, tets(1, e)), x(:, tets(2, e)), x(:, tets(3, e)), x(:, tets(4, e)))
                    if (all(lam >= 0)) then
                        write (msg, '(a,i0,a,i0,a,i0,a,i0,a)') 'bodies ', min(bi, bj), ' and ', max(bi, bj), &
                            ' overlap in the initial state (node ', i, ' of body ', bi, ' lies inside the other body)'
                        ok = .false.
                        return
                    end if
                end do
            end do
        end do
        ! boundary nodes of different bodies closer than d0 (already in contact)
        do i = 1, n
            bi = self%tag_of_id(i)
            if (bi == 0) cycle
            do j = i + 1, n
                bj = self%tag_of_id(j)
                if (bj == 0 .or. bj == bi) cycle
                if (any(abs(x(:, i) - x(:, j)) >= self%d0)) cycle
                r = norm2(x(:, i) - x(:, j))
                if (r < self%d0) then
                    write (msg, '(a,i0,a,i0,a,i0,a,i0,a,es10.3,a,es10.3,a)') 'bodies ', min(bi, bj), ' and ', max(bi, bj), &
                        ' overlap in the initial state (boundary nodes ', i, ' and ', j, ' are ', r, &
                        ' apart, within contact_distance = ', self%d0, '): start them further apart'
                    ok = .false.
                    return
                end if
            end do
        end do
    contains
        pure function barycentric(p, a0, a1, a2, a3) result(l)
            real(dp), intent(in) :: p(3), a0(3), a1(3), a2(3), a3(3)
            real(dp) :: l(4), m(3, 3), d, q(3)
            m(:, 1) = a1 - a0; m(:, 2) = a2 - a0; m(:, 3) = a3 - a0
            q = p - a0
            d = tri(m(:, 1), m(:, 2), m(:, 3))
            l(2) = tri(q, m(:, 2), m(:, 3))/d
            l(3) = tri(m(:, 1), q, m(:, 3))/d
            l(4) = tri(m(:, 1), m(:, 2), q)/d
            l(1) = 1 - l(2) - l(3) - l(4)
        end function barycentric
        pure real(dp) function tri(a, b, c)
            real(dp), intent(in) :: a(3), b(3), c(3)
            tri = a(1)*(b(2)*c(3) - b(3)*c(2)) - a(2)*(b(1)*c(3) - b(3)*c(1)) + a(3)*(b(1)*c(2) - b(2)*c(1))
        end function tri
    end subroutine ct_check_start

    !> Local indices have changed: each atom's tag (body if a boundary node, else 0); the candidate
    !> pairs are refiltered at the next pass.
    subroutine ct_on_rebuild(self, atoms)
        class(contact_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        integer :: i, nall
        integer(i8) :: id
        nall = atoms%nall()
        if (allocated(self%tag)) then
            if (size(self%tag) < nall) deallocate (self%tag)
        end if
        if (.not. allocated(self%tag)) allocate (self%tag(max(nall, 1)))
        do i = 1, nall
            id = atoms%id(i)
            self%tag(i) = 0
            if (id >= 1 .and. id <= size(self%tag_of_id)) self%tag(i) = self%tag_of_id(id)
        end do
        self%stale = .true.
    end subroutine ct_on_rebuild

    !> The pairs of the half list whose atoms are boundary nodes of different bodies.
    subroutine filter_pairs(self, list, nlocal)
        class(contact_t), intent(inout) :: self
        type(neighbor_list_t), intent(in) :: list
        integer, intent(in) :: nlocal
        integer :: i, j, k, n, pass, ti
        if (.not. allocated(list%first)) then
            self%npair = 0
            self%stale = .false.
            return
        end if
        do pass = 1, 2
            n = 0
            do i = 1, nlocal
                ti = self%tag(i)
                if (ti == 0) cycle
                do k = list%first(i), list%first(i + 1) - 1
                    j = list%neigh(k)
                    if (self%tag(j) == 0 .or. self%tag(j) == ti) cycle
                    n = n + 1
                    if (pass == 2) then
                        self%pi(n) = i; self%pj(n) = j
                    end if
                end do
            end do
            if (pass == 1) then
                if (allocated(self%pi)) then
                    if (size(self%pi) < n) deallocate (self%pi, self%pj)
                end if
                if (.not. allocated(self%pi)) allocate (self%pi(max(n, 16)), self%pj(max(n, 16)))
            end if
        end do
        self%npair = n
        self%stale = .false.
    end subroutine filter_pairs

    subroutine ct_forces(self, atoms, list, halo, want_energy, energy, virial)
        class(contact_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        type(neighbor_list_t), intent(in) :: list
        class(halo_ops_t), intent(inout) :: halo
        logical, intent(in) :: want_energy
        real(dp), intent(out) :: energy, virial
        integer :: p, i, j
        real(dp) :: dx(3), r2, r, gap, fr(3), d0sq
        if (self%stale) call filter_pairs(self, list, atoms%nlocal)
        energy = 0; virial = 0
        d0sq = self%d0**2
        do p = 1, self%npair
            i = self%pi(p); j = self%pj(p)
            dx = atoms%x(:, i) - atoms%x(:, j)
            r2 = dx(1)*dx(1) + dx(2)*dx(2) + dx(3)*dx(3)
            if (r2 >= d0sq) cycle
            r = sqrt(r2)
            gap = self%d0 - r
            if (r > 0) then
                fr = (self%k*gap/r)*dx
            else
                fr = 0       ! coincident nodes: no direction (never reached from a valid start)
            end if
            atoms%f(:, i) = atoms%f(:, i) + fr
            atoms%f(:, j) = atoms%f(:, j) - fr
            energy = energy + 0.5_dp*self%k*gap*gap
            virial = virial + self%k*gap*r
        end do
    end subroutine ct_forces

    subroutine ct_ray(self, atoms, list, s, out)
        class(contact_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        type(neighbor_list_t), intent(in) :: list
        real(dp), intent(in) :: s
        real(dp), intent(out) :: out(4)
        integer :: p, i, j
        real(dp) :: dx(3), dv(3), r2, r, gap, a, b, r1, rr, d0sq
        if (self%stale) call filter_pairs(self, list, atoms%nlocal)
        out = 0
        d0sq = self%d0**2
        do p = 1, self%npair
            i = self%pi(p); j = self%pj(p)
            dv = atoms%v(:, i) - atoms%v(:, j)
            dx = atoms%x(:, i) - atoms%x(:, j) + s*dv
            r2 = dx(1)*dx(1) + dx(2)*dx(2) + dx(3)*dx(3)
            if (r2 >= d0sq .or. .not. (r2 > 0)) cycle
            r = sqrt(r2)
            gap = self%d0 - r
            a = dv(1)*dv(1) + dv(2)*dv(2) + dv(3)*dv(3)
            b = dx(1)*dv(1) + dx(2)*dv(2) + dx(3)*dv(3)
            r1 = b/r
            rr = (a - r1*r1)/r
            out(1) = out(1) + 0.5_dp*self%k*gap*gap
            out(2) = out(2) - self%k*gap*r1
            out(3) = out(3) + self%k*(r1*r1 - gap*rr)
            out(4) = out(4) + self%k*gap*r
        end do
    end subroutine ct_ray

    pure real(dp) function ct_cutoff(self)
        class(contact_t), intent(in) :: self
        ct_cutoff = self%d0
    end function ct_cutoff

    !> The list's skin when the deck gives none: half the contact distance (the list is rebuilt
    !> when a node has moved d0/4).
    pure real(dp) function ct_preferred_skin(self)
        class(contact_t), intent(in) :: self
        ct_preferred_skin = 0.5_dp*self%d0
    end function ct_preferred_skin

    !> tau with 0.005 tau = 1/(2 omega), omega^2 = 8 k / m_min: a boundary node held by a few
    !> contact springs on each side, at a quarter of Verlet's limit 2/omega.
    pure real(dp) function ct_time_scale(self, mass, mvv2e)
        class(contact_t), intent(in) :: self
        real(dp), intent(in) :: mass, mvv2e
        ct_time_scale = 0
        if (self%min_mass > 0 .and. self%k > 0) ct_time_scale = 100*sqrt(self%min_mass/(8*self%k))
    end function ct_time_scale

    function ct_describe(self) result(text)
        class(contact_t), intent(in) :: self
        character(len=:), allocatable :: text
        character(len=300) :: s
        write (s, '(a,i0,a,i0,a,es11.4,a,es11.4,a,es11.4,a)') 'contact between ', self%nbodies, ' bodies (', &
            self%nboundary, ' boundary nodes): k/2 (d0 - r)^2, k = ', self%k, ', d0 = ', self%d0, &
            ' (mean boundary edge ', self%spacing, '); pairs of boundary nodes of different bodies from the list'
        text = trim(s)
    end function ct_describe


    !> The bounding box of each body's nodes (node_body(i) < 1: a node in no body).
    pure subroutine body_boxes(x, node_body, lo, hi)
        real(dp), intent(in) :: x(:, :)
        integer, intent(in) :: node_body(:)
        real(dp), intent(out) :: lo(:, :), hi(:, :)
        integer :: i
        lo = huge(1.0_dp); hi = -huge(1.0_dp)
        do i = 1, size(node_body)
            if (node_body(i) < 1) cycle
            lo(:, node_body(i)) = min(lo(:, node_body(i)), x(:, i))
            hi(:, node_body(i)) = max(hi(:, node_body(i)), x(:, i))
        end do
    end subroutine body_boxes

end module terrace_contact
