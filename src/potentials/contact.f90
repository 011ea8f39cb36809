!> Frictionless contact between the bodies of a mesh (doc/contact.md), two models
!> (&potential contact_model):
!>
!> node_face (the default): a barrier between each boundary node p of one body and each boundary
!> triangle T of another,
!>   V = sum over (p, T), body(p) /= body(T), d(p, T) < d0:  k/2 (d0 - d)^2,
!> d the Euclidean point-triangle distance (closest point c in the face, on an edge or at a vertex:
!> terrace_point_triangle). Continuous with a continuous gradient for d > 0. Force on p:
!> k (d0 - d) n, n = (p - c)/d; on T's vertices minus it times the closest point's barycentric
!> weights w_i: the forces sum to zero and, acting along the line p - c with c = sum w_i x_i,
!> their torques cancel. Virial: sum x.f = k (d0 - d) d. Along the ray the closest point's region is
!> found at each s and d, d', d'' come in closed form per region (point_triangle.f90's header):
!>   V' = -k (d0 - d) d',  V'' = k d'^2 - k (d0 - d) d''.
!> Candidates, once per list build: for every list pair (i, j) of boundary nodes of different
!> bodies with i or j owned here, the faces around j with node i and the faces around i with node j,
!> sorted by (node id, face) without repeats. The list cutoff is d0 + (5/4) L, L the longest
!> reference boundary edge: when d(p, T) < d0, every vertex of T lies within d0 + (current longest
!> edge of T) of p, so with edges stretched by up to 25 % the pair (p, vertex) is in the list (cutoff
!> + skin at the build, valid while no node has moved skin/2) for all three vertices, in particular
!> for an owned one; the halo reaches as far. Rank invariance: each rank computes every candidate
!> that has an owned node (the node or a vertex) and adds forces to owned nodes only, in the
!> candidates' (node id, face) order: every node's force has the same bits on any number of ranks.
!> A pair's energy and virial count on the rank owning its node.
!>
!> node_node: a pair barrier between boundary nodes of different bodies,
!>   V = sum over pairs (i, j), body(i) /= body(j), r_ij < d0:  k/2 (d0 - r_ij)^2,
!> central forces, equal and opposite. Candidates: the engine's half neighbour list (cutoff d0 +
!> skin), filtered once per list build into the pairs of boundary nodes of different bodies.
!> Along the ray x + s v: with dx = x_i - x_j, dv = v_i - v_j, r(s)^2 = |dx|^2 + 2 s dx.dv + s^2 |dv|^2,
!>   r' = (dx.dv + s |dv|^2)/r,  r'' = (|dv|^2 - r'^2)/r,
!>   V' = -k (d0 - r) r',  V'' = k r'^2 - k (d0 - r) r'',  W = k (d0 - r) r   (virial x.f).
!>
!> Boundary nodes and faces: the faces that belong to exactly one tetrahedron, and their nodes.
!> Defaults (doc/contact.md), h_b the mean boundary edge, E Young's modulus of the elements:
!> k = E h_b (the stiffness E A / t of a cube of the material one boundary edge wide), and
!> d0 = h_b / 2 for node_face (a thin layer: the surfaces touch d0 apart), d0 = h_b for node_node
!> (a node must meet the nodes of the other body before it can pass between them: d0 above the
!> boundary triangles' circumradius, about 0.6 h_b).
module terrace_contact
    use terrace_kinds, only: dp, i8
    use terrace_atoms, only: atoms_t
    use terrace_neighbor_list, only: neighbor_list_t
    use terrace_grow, only: reserve
    use terrace_potential, only: potential_t, halo_ops_t
    use terrace_point_triangle, only: closest_point, distance_derivatives
    use terrace_heap_sort, only: sort_by_id
    implicit none
    private

    integer, parameter, public :: model_node_face = 1, model_node_node = 2
    real(dp), parameter :: edge_allowance = 1.25_dp   !< boundary edges may stretch this much (list cutoff)

    type, extends(potential_t), public :: contact_t
        real(dp) :: k = 0, d0 = 0
        integer :: model = model_node_face
        real(dp) :: max_edge = 0                    !< longest reference boundary edge
        ! node_face: boundary faces by node id, faces(3, nface), the faces around each node (CSR)
        integer :: nface = 0
        integer, allocatable :: faces(:, :), face_first(:), face_of(:)
        integer, allocatable :: id_map(:)           !< scratch: node id -> local index (0: not here)
        integer(i8), allocatable :: keys(:)         !< scratch: candidate keys (node id - 1) nface + face
        integer, allocatable :: order(:)            !< scratch: the keys' sorted order
        ! node_face candidates (after the first pass past a build): node, face vertices (local)
        integer :: ncand = 0
        integer, allocatable :: cand(:, :)          !< (4, ncand): p, a, b, c local indices
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
        !> a state the contact search cannot serve (a boundary edge stretched beyond the list's reach),
        !> reported by invalid_state
        character(len=:), allocatable :: problem
    contains
        procedure :: setup => ct_setup
        procedure :: check_start => ct_check_start
        procedure :: forces => ct_forces
        procedure :: ray => ct_ray
        procedure :: cutoff => ct_cutoff
        procedure :: describe => ct_describe
        procedure :: on_rebuild => ct_on_rebuild
        procedure :: time_unit => ct_time_unit
        procedure :: preferred_skin => ct_preferred_skin
        procedure :: needs_full_neighbourhood => ct_needs_full
        procedure :: list_problem => ct_list_problem
        procedure :: may_become_invalid => ct_may_become_invalid
    end type contact_t

    public :: boundary_nodes, boundary_edges

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

    !> The mean and the longest edge of the boundary faces faces(3, nf) (node ids into x(3, id)): h_b of
    !> the defaults and the reach of the contact search. An edge counts once for each face it bounds.
    pure subroutine boundary_edges(x, faces, mean, longest)
        real(dp), intent(in) :: x(:, :)
        integer, intent(in) :: faces(:, :)
        real(dp), intent(out) :: mean, longest
        real(dp) :: sum_edge, edge
        integer :: q, a
        sum_edge = 0
        longest = 0
        do q = 1, size(faces, 2)
            do a = 1, 3
                edge = norm2(x(:, faces(a, q)) - x(:, faces(mod(a, 3) + 1, q)))
                sum_edge = sum_edge + edge
                longest = max(longest, edge)
            end do
        end do
        mean = sum_edge/max(3*size(faces, 2), 1)
    end subroutine boundary_edges

    !> The term for a mesh: tets(4, ne) by node id, body(ne) the physical volume of each
    !> tetrahedron, xref(3, id) reference positions, node_mass (lumped, for the time scale); model
    !> model_node_face (default) or model_node_node. k <= 0 or d0 <= 0: the defaults (E h_b; h_b/2
    !> for node_face, h_b for node_node; h_b the mean boundary edge, E the elements' Young's modulus).
    subroutine ct_setup(self, k, d0, youngs, tets, body, xref, node_mass, model)
        class(contact_t), intent(inout) :: self
        real(dp), intent(in) :: k, d0, youngs
        integer, intent(in), optional :: model
        real(dp), intent(in) :: node_mass(:)      !< lumped node masses by id (the scene's)
        integer(i8), intent(in) :: tets(:, :)
        integer, intent(in) :: body(:)
        real(dp), intent(in) :: xref(:, :)
        logical, allocatable :: bnd(:)
        real(dp), allocatable :: lo(:, :), hi(:, :)
        integer, allocatable :: node_body(:), faces(:, :)
        integer :: nnode, e, a, q, nb
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
        call boundary_edges(xref, faces, self%spacing, self%max_edge)
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
        self%model = model_node_face
        if (present(model)) self%model = model
        self%d0 = d0
        if (.not. (d0 > 0)) self%d0 = merge(0.5_dp, 1.0_dp, self%model == model_node_face)*self%spacing
        self%k = k
        if (.not. (k > 0)) self%k = youngs*self%spacing
        ! node_face: the boundary faces, the faces around each node
        self%nface = size(faces, 2)
        allocate (self%face_first(nnode + 1), self%face_of(3*self%nface))
        self%face_first = 0
        do q = 1, self%nface
            do a = 1, 3
                self%face_first(faces(a, q) + 1) = self%face_first(faces(a, q) + 1) + 1
            end do
        end do
        self%face_first(1) = 1
        do a = 1, nnode
            self%face_first(a + 1) = self%face_first(a + 1) + self%face_first(a)
        end do
        node_body(1:nnode) = self%face_first(1:nnode)      ! fill pointers (node_body no longer needed)
        do q = 1, self%nface
            do a = 1, 3
                self%face_of(node_body(faces(a, q))) = q
                node_body(faces(a, q)) = node_body(faces(a, q)) + 1
            end do
        end do
        call move_alloc(faces, self%faces)
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
        if (self%model == model_node_face) then
            call check_start_faces(self, x, ok, msg)
            return
        end if
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

    !> node_face: a boundary node of one body closer than d0 to a boundary face of another.
    subroutine check_start_faces(self, x, ok, msg)
        class(contact_t), intent(in) :: self
        real(dp), intent(in) :: x(:, :)
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        real(dp) :: w(3), d, flo(3), fhi(3)
        integer :: i, q, bi, bj, region
        ok = .true.; msg = ''
        do q = 1, self%nface
            bj = self%tag_of_id(self%faces(1, q))
            flo = min(min(x(:, self%faces(1, q)), x(:, self%faces(2, q))), x(:, self%faces(3, q))) - self%d0
            fhi = max(max(x(:, self%faces(1, q)), x(:, self%faces(2, q))), x(:, self%faces(3, q))) + self%d0
            do i = 1, size(x, 2)
                bi = self%tag_of_id(i)
                if (bi == 0 .or. bi == bj) cycle
                if (any(x(:, i) < flo) .or. any(x(:, i) > fhi)) cycle
                call closest_point(x(:, i), x(:, self%faces(1, q)), x(:, self%faces(2, q)), x(:, self%faces(3, q)), w, region)
                d = norm2(x(:, i) - w(1)*x(:, self%faces(1, q)) - w(2)*x(:, self%faces(2, q)) - w(3)*x(:, self%faces(3, q)))
                if (d < self%d0) then
                    write (msg, '(a,i0,a,i0,a,i0,a,3(i0,1x),a,es10.3,a,es10.3,a)') 'bodies ', min(bi, bj), ' and ', &
                        max(bi, bj), ' overlap in the initial state (boundary node ', i, ' and face ', self%faces(:, q), &
                        'are ', d, ' apart, within contact_distance = ', self%d0, '): start them further apart'
                    ok = .false.
                    return
                end if
            end do
        end do
    end subroutine check_start_faces

    !> Local indices have changed: each atom's tag (body if a boundary node, else 0); the candidate
    !> pairs are refiltered at the next pass.
    subroutine ct_on_rebuild(self, atoms)
        class(contact_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        integer :: i, nall
        integer(i8) :: id
        nall = atoms%nall()
        call reserve(self%tag, nall, minimum=1, exact=.true.)
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
                call reserve(self%pi, n, minimum=16, exact=.true.)
                call reserve(self%pj, n, minimum=16, exact=.true.)
            end if
        end do
        self%npair = n
        self%stale = .false.
    end subroutine filter_pairs

    !> The candidates of the model (node-face or node-node pairs) after a list build.
    subroutine refresh_candidates(self, atoms, list)
        class(contact_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        type(neighbor_list_t), intent(in) :: list
        if (self%model == model_node_face) then
            call build_candidates(self, atoms, list)
        else
            call filter_pairs(self, list, atoms%nlocal)
        end if
    end subroutine refresh_candidates

    subroutine ct_forces(self, atoms, list, halo, want_energy, energy, virial)
        class(contact_t), intent(inout) :: self
        include 'potential_forces_args.inc'
        integer :: p, i, j
        real(dp) :: dx(3), r2, r, gap, fr(3), d0sq
        if (self%stale) call refresh_candidates(self, atoms, list)
        if (self%model == model_node_face) then
            call face_forces(self, atoms, energy, virial)
            return
        end if
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
        include 'potential_ray_args.inc'
        integer :: p, i, j
        real(dp) :: dx(3), dv(3), r2, r, gap, a, b, r1, rr, d0sq
        if (self%stale) call refresh_candidates(self, atoms, list)
        if (self%model == model_node_face) then
            call face_ray(self, atoms, s, out)
            return
        end if
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
            out = out + barrier_ray(self%k, gap, r, r1, rr)
        end do
    end subroutine ct_ray

    !> One pair's barrier k/2 gap^2 (gap = d0 - d) along the ray, from the distance d and its
    !> derivatives d1, d2 along it: V, V' = -k gap d1, V'' = k (d1^2 - gap d2), and the virial k gap d.
    pure function barrier_ray(k, gap, d, d1, d2) result(o)
        real(dp), intent(in) :: k, gap, d, d1, d2
        real(dp) :: o(4)
        o = [0.5_dp*k*gap*gap, -k*gap*d1, k*(d1*d1 - gap*d2), k*gap*d]
    end function barrier_ray

    !> node_node: d0. node_face: d0 + 5/4 of the longest boundary edge, so that a node within d0 of a
    !> face is within the cutoff of all three of its vertices (module header).
    pure real(dp) function ct_cutoff(self)
        class(contact_t), intent(in) :: self
        ct_cutoff = self%d0
        if (self%model == model_node_face) ct_cutoff = self%d0 + edge_allowance*self%max_edge
    end function ct_cutoff

    !> node_face builds its candidates from each owned node's whole neighbourhood (the half list and
    !> its complement of ghosts below): a pair whose only owned node is a face vertex must be found.
    pure logical function ct_needs_full(self, energy_stepping)
        class(contact_t), intent(in) :: self
        logical, intent(in) :: energy_stepping
        ct_needs_full = self%model == model_node_face
    end function ct_needs_full

    !> node_face candidates from the list: for each list pair (i, j) of boundary nodes of different
    !> bodies (i owned; j from the half list or its complement below), the faces around j with node
    !> i and the faces around i with node j; sorted by key (node id - 1) nface + face (heap sort),
    !> without repeats, so that the force pass's order does not depend on the partition. Each candidate
    !> has an owned node (i as the node, or i as a face vertex).
    subroutine build_candidates(self, atoms, list)
        class(contact_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        type(neighbor_list_t), intent(in) :: list
        integer :: i, m, n, nlocal, nall, pass, c, q
        integer(i8) :: key, pid
        logical :: have_below
        nlocal = atoms%nlocal
        nall = atoms%nall()
        self%ncand = 0
        self%stale = .false.
        if (.not. allocated(list%first)) return
        have_below = allocated(list%below_first)
        if (have_below) have_below = size(list%below_first) >= nlocal + 1
        if (.not. allocated(self%id_map)) allocate (self%id_map(size(self%tag_of_id)))
        self%id_map = 0
        do i = nall, 1, -1          ! owned atoms last: an owned copy wins
            if (atoms%id(i) >= 1 .and. atoms%id(i) <= size(self%id_map)) self%id_map(atoms%id(i)) = i
        end do
        call check_stretch(self, atoms, list%skin)
        if (allocated(self%problem)) return        ! (the run stops at the engine's check after this pass)
        do pass = 1, 2
            n = 0
            do i = 1, nlocal
                if (self%tag(i) == 0) cycle
                do m = list%first(i), list%first(i + 1) - 1
                    call add_pair(i, list%neigh(m))
                end do
                if (.not. have_below) cycle
                do m = list%below_first(i), list%below_first(i + 1) - 1
                    call add_pair(i, list%below(m))
                end do
            end do
            if (pass == 1) then
                if (allocated(self%keys)) then
                    if (size(self%keys) < n) deallocate (self%keys)
                end if
                if (.not. allocated(self%keys)) allocate (self%keys(max(n, 64)))
            end if
        end do
        if (allocated(self%order)) then
            if (size(self%order) < n) deallocate (self%order)
        end if
        if (.not. allocated(self%order)) allocate (self%order(size(self%keys)))
        self%order(1:n) = [(m, m = 1, n)]
        call sort_by_id(self%keys(1:n), self%order(1:n))
        if (allocated(self%cand)) then
            if (size(self%cand, 2) < n) deallocate (self%cand)
        end if
        if (.not. allocated(self%cand)) allocate (self%cand(4, max(n, 64)))
        c = 0
        do m = 1, n
            if (m > 1) then          ! repeats (a pair found through several vertices) once
                if (self%keys(self%order(m)) == self%keys(self%order(m - 1))) cycle
            end if
            key = self%keys(self%order(m)) - 1
            pid = key/self%nface + 1
            q = int(mod(key, int(self%nface, i8))) + 1
            c = c + 1
            self%cand(1, c) = self%id_map(pid)
            self%cand(2:4, c) = self%id_map(self%faces(:, q))
            if (any(self%cand(:, c) == 0)) then     ! a vertex not on this rank (halo too short): skip
                c = c - 1
                cycle
            end if
        end do
        self%ncand = c
    contains
        subroutine add_pair(i, j)
            integer, intent(in) :: i, j
            if (self%tag(j) == 0 .or. self%tag(j) == self%tag(i)) return
            call add_faces(atoms%id(i), atoms%id(j))
            call add_faces(atoms%id(j), atoms%id(i))
        end subroutine add_pair
        !> (node p, each face around node a)
        subroutine add_faces(p, a)
            integer(i8), intent(in) :: p, a
            integer :: f
            do f = self%face_first(a), self%face_first(a + 1) - 1
                n = n + 1
                if (pass == 2) self%keys(n) = (p - 1)*self%nface + self%face_of(f)
            end do
        end subroutine add_faces
    end subroutine build_candidates

    !> The list cutoff holds every pair within d0 only while no boundary edge is longer than
    !> edge_allowance times the longest reference edge; edges grow by at most the skin before the
    !> next build. Every owned boundary node's edges are checked at each build: a longer edge, or a
    !> face vertex missing on this rank, is recorded (`problem`), and the engine's collective check
    !> after the force pass (list_problem) stops every rank with it, rather than miss contact pairs silently.
    subroutine check_stretch(self, atoms, skin)
        class(contact_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        real(dp), intent(in) :: skin
        integer :: i, f, a, v
        real(dp) :: limit, len
        character(len=320) :: text
        limit = edge_allowance*self%max_edge - skin
        if (limit <= 0 .and. atoms%nlocal > 0) then
            write (text, '(a,es11.3e3,a,es11.3e3,a)') 'contact: &neighbor skin = ', skin, ' leaves the contact search '// &
                'no reach (it must stay below ', edge_allowance*self%max_edge, ', the allowance for boundary edges '// &
                'to stretch before the next list build; the default skin is half the contact distance)'
            if (.not. allocated(self%problem)) self%problem = trim(text)
            return
        end if
        do i = 1, atoms%nlocal
            if (self%tag(i) == 0) cycle
            do f = self%face_first(atoms%id(i)), self%face_first(atoms%id(i) + 1) - 1
                do a = 1, 3
                    v = self%id_map(self%faces(a, self%face_of(f)))
                    len = huge(1.0_dp)
                    if (v > 0) len = norm2(atoms%x(:, v) - atoms%x(:, i))
                    if (len <= limit) cycle
                    write (text, '(a,i0,a,i0,a,es11.3e3,a,es11.3e3,a,f0.2,a,es11.3e3,a,es11.3e3,a)') &
                        'contact: the boundary edge of nodes ', atoms%id(i), ' and ', &
                        self%faces(a, self%face_of(f)), ' has stretched to ', len, ', beyond the ', limit, &
                        ' the contact search allows (', edge_allowance, ' x the longest reference boundary edge ', &
                        self%max_edge, ' less &neighbor skin = ', skin, '): it would miss pairs; the deformation '// &
                        'is beyond the mesh, or the skin is too large (&neighbor skin)'
                    if (.not. allocated(self%problem)) self%problem = trim(text)
                    return
                end do
            end do
        end do
    end subroutine check_stretch

    !> node_face forces: each candidate in key order; forces added to owned nodes only (so each owned
    !> node sums its pairs in the same order on any number of ranks), energy and virial where the
    !> node is owned.
    subroutine face_forces(self, atoms, energy, virial)
        class(contact_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        real(dp), intent(out) :: energy, virial
        integer :: c, ip, nlocal, a
        real(dp) :: w(3), dx(3), d2, d, gap, fr(3), d0sq
        integer :: region
        nlocal = atoms%nlocal
        energy = 0; virial = 0
        d0sq = self%d0**2
        do c = 1, self%ncand
            ip = self%cand(1, c)
            call closest_point(atoms%x(:, ip), atoms%x(:, self%cand(2, c)), atoms%x(:, self%cand(3, c)), &
                               atoms%x(:, self%cand(4, c)), w, region)
            dx = atoms%x(:, ip) - w(1)*atoms%x(:, self%cand(2, c)) - w(2)*atoms%x(:, self%cand(3, c)) - &
                 w(3)*atoms%x(:, self%cand(4, c))
            d2 = dx(1)*dx(1) + dx(2)*dx(2) + dx(3)*dx(3)
            if (d2 >= d0sq .or. .not. (d2 > 0)) cycle      ! d = 0: no direction (never from a valid start)
            d = sqrt(d2)
            gap = self%d0 - d
            fr = (self%k*gap/d)*dx
            if (ip <= nlocal) atoms%f(:, ip) = atoms%f(:, ip) + fr
            do a = 1, 3
                if (self%cand(a + 1, c) <= nlocal) atoms%f(:, self%cand(a + 1, c)) = atoms%f(:, self%cand(a + 1, c)) - w(a)*fr
            end do
            if (ip > nlocal) cycle                          ! the pair's energy counts on its node's rank
            energy = energy + 0.5_dp*self%k*gap*gap
            virial = virial + self%k*gap*d
        end do
    end subroutine face_forces

    !> node_face along the ray: per candidate the region at x + s v, then d, d', d'' in closed form.
    subroutine face_ray(self, atoms, s, out)
        class(contact_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        real(dp), intent(in) :: s
        real(dp), intent(out) :: out(4)
        integer :: c, a, region
        real(dp) :: y(3, 4), v(3, 4), w(3), dx(3), d2, d0sq, d, d1, dd
        out = 0
        d0sq = self%d0**2
        do c = 1, self%ncand
            if (self%cand(1, c) > atoms%nlocal) cycle       ! V counts each pair on its node's rank
            do a = 1, 4
                v(:, a) = atoms%v(:, self%cand(a, c))
                y(:, a) = atoms%x(:, self%cand(a, c)) + s*v(:, a)
            end do
            call closest_point(y(:, 1), y(:, 2), y(:, 3), y(:, 4), w, region)
            dx = y(:, 1) - w(1)*y(:, 2) - w(2)*y(:, 3) - w(3)*y(:, 4)
            d2 = dx(1)*dx(1) + dx(2)*dx(2) + dx(3)*dx(3)
            if (d2 >= d0sq .or. .not. (d2 > 0)) cycle
            call distance_derivatives(y, v, region, d, d1, dd)
            out = out + barrier_ray(self%k, self%d0 - d, d, d1, dd)
        end do
    end subroutine face_ray

    !> The list's skin when the deck gives none: half the contact distance (the list is rebuilt
    !> when a node has moved d0/4; node_face: the same d0/2, which its larger cutoff covers too).
    pure real(dp) function ct_preferred_skin(self)
        class(contact_t), intent(in) :: self
        ct_preferred_skin = 0.5_dp*self%d0
    end function ct_preferred_skin

    !> tau with 0.005 tau = 1/(2 omega), omega^2 = 8 k / m_min: a boundary node held by a few
    !> contact springs on each side, at a quarter of Verlet's limit 2/omega.
    pure subroutine ct_time_unit(self, mass, mvv2e, tau, words)
        class(contact_t), intent(in) :: self
        real(dp), intent(in) :: mass, mvv2e
        real(dp), intent(out) :: tau
        character(len=:), allocatable, intent(out) :: words
        tau = 0
        if (self%min_mass > 0 .and. self%k > 0) tau = 100*sqrt(self%min_mass/(8*self%k))
        words = 'a quarter of Verlet''s limit on the contact springs'
    end subroutine ct_time_unit

    function ct_describe(self) result(text)
        class(contact_t), intent(in) :: self
        character(len=:), allocatable :: text
        character(len=400) :: s
        if (self%model == model_node_face) then
            write (s, '(a,i0,a,i0,a,i0,a,es11.4,a,es11.4,a,es11.4,a,es11.4,a)') 'contact (node_face) between ', &
                self%nbodies, ' bodies (', self%nboundary, ' boundary nodes, ', self%nface, &
                ' boundary faces): k/2 (d0 - d)^2, d the node-triangle distance, k = ', self%k, ', d0 = ', self%d0, &
                ' (mean boundary edge ', self%spacing, ', list cutoff ', self%cutoff(), &
                '); (node, face) pairs of different bodies from the list'
        else
            write (s, '(a,i0,a,i0,a,es11.4,a,es11.4,a,es11.4,a)') 'contact (node_node) between ', self%nbodies, &
                ' bodies (', self%nboundary, ' boundary nodes): k/2 (d0 - r)^2, k = ', self%k, ', d0 = ', self%d0, &
                ' (mean boundary edge ', self%spacing, '); pairs of boundary nodes of different bodies from the list'
        end if
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

    !> A boundary edge stretched beyond the contact search's reach (check_stretch) at the last build.
    logical function ct_list_problem(self, text) result(bad)
        class(contact_t), intent(in) :: self
        character(len=*), intent(out) :: text
        bad = allocated(self%problem)
        text = ''
        if (bad) text = self%problem
    end function ct_list_problem

    pure logical function ct_may_become_invalid(self)
        class(contact_t), intent(in) :: self
        ct_may_become_invalid = .true.
    end function ct_may_become_invalid

end module terrace_contact
