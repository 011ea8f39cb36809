!> Rigid planar walls for the boundary nodes of a mesh (doc/contact.md, "Walls"). Wall w is the
!> plane through a point q_w with unit normal n_w, pointing to the side the mesh is on; a node x has
!> the signed distance d_w(x) = n_w . x - n_w . q_w. Each boundary node is held off each wall by the
!> barrier of the contact between bodies,
!>   V = sum over boundary nodes i, walls w, d_w(x_i) < d0:  k/2 (d0 - d_w(x_i))^2,
!> force on the node k (d0 - d) n_w (the wall is rigid: nothing acts back), virial x . f =
!> k (d0 - d) (n_w . x). Continuous with a continuous gradient; for d < 0 (a node pushed through the
!> plane) the same quadratic keeps pushing it back. Along the ray x + s v the distance is linear,
!> d(s) = d + s (n_w . v), so d' = n_w . v and d'' = 0:
!>   V' = -k (d0 - d) d',  V'' = k d'^2  (exact; V'' jumps at d = d0, a kink the event solver brackets).
!> Rank invariance: each rank evaluates its owned boundary nodes only, each node summing the walls in
!> their order, so every node's force has the same bits on any number of ranks; no state, no
!> neighbour list, no halo. Defaults (as node_face contact), h_b the mean boundary edge and E the
!> elements' Young's modulus: k = E h_b, d0 = h_b / 2.
module terrace_walls
    use terrace_kinds, only: dp, i8
    use terrace_atoms, only: atoms_t
    use terrace_neighbor_list, only: neighbor_list_t
    use terrace_grow, only: reserve
    use terrace_potential, only: potential_t, halo_ops_t
    use terrace_contact, only: boundary_nodes, boundary_edges
    implicit none
    private

    type, extends(potential_t), public :: walls_t
        real(dp) :: k = 0, d0 = 0
        integer :: nwall = 0
        real(dp), allocatable :: normal(:, :)       !< (3, nwall) unit normals, towards the mesh
        real(dp), allocatable :: offset(:)          !< n_w . q_w: d = n_w . x - offset(w)
        logical, allocatable :: boundary_of_id(:)   !< by node id
        integer :: nboundary = 0
        real(dp) :: spacing = 0                     !< mean boundary edge (the defaults' h_b)
        real(dp) :: min_mass = 0                    !< lightest boundary node (lumped), for the time scale
        integer :: nmine = 0
        integer, allocatable :: mine(:)             !< local indices of the owned boundary nodes
    contains
        procedure :: setup => walls_setup
        procedure :: check_start => walls_check_start
        procedure :: forces => walls_forces
        procedure :: ray => walls_ray
        procedure :: cutoff => walls_cutoff
        procedure :: describe => walls_describe
        procedure :: needs_pair_list => walls_needs_pair_list
        procedure :: on_rebuild => walls_on_rebuild
        procedure :: time_unit => walls_time_unit
    end type walls_t

contains

    !> planes(6, nwall): a point of each plane and its normal (any length > 0, towards the mesh);
    !> tets(4, ne) by node id, xref(3, id) the reference nodes, node_mass (lumped, by id); k <= 0 or
    !> d0 <= 0: the defaults E h_b and h_b / 2.
    subroutine walls_setup(self, planes, k, d0, youngs, tets, xref, node_mass)
        class(walls_t), intent(inout) :: self
        real(dp), intent(in) :: planes(:, :), k, d0, youngs
        integer(i8), intent(in) :: tets(:, :)
        real(dp), intent(in) :: xref(:, :), node_mass(:)
        integer, allocatable :: faces(:, :)
        real(dp) :: longest
        integer :: w, nnode
        self%nwall = size(planes, 2)
        allocate (self%normal(3, self%nwall), self%offset(self%nwall))
        do w = 1, self%nwall
            self%normal(:, w) = planes(4:6, w)/norm2(planes(4:6, w))
            self%offset(w) = dot_product(self%normal(:, w), planes(1:3, w))
        end do
        nnode = size(xref, 2)
        allocate (self%boundary_of_id(nnode))
        call boundary_nodes(tets, nnode, self%boundary_of_id, faces)
        self%nboundary = count(self%boundary_of_id)
        call boundary_edges(xref, faces, self%spacing, longest)
        self%min_mass = minval(node_mass(1:nnode), mask=self%boundary_of_id)
        self%k = k
        if (.not. (k > 0)) self%k = youngs*self%spacing
        self%d0 = d0
        if (.not. (d0 > 0)) self%d0 = 0.5_dp*self%spacing
    end subroutine walls_setup

    !> Refuse a start with a boundary node closer than d0 to a wall (or behind it). x(3, id): the
    !> starting positions. ok = .false. with a message naming the node and the wall.
    subroutine walls_check_start(self, x, ok, msg)
        class(walls_t), intent(in) :: self
        real(dp), intent(in) :: x(:, :)
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        integer :: i, w
        real(dp) :: d
        ok = .true.; msg = ''
        do w = 1, self%nwall
            do i = 1, size(x, 2)
                if (.not. self%boundary_of_id(i)) cycle
                d = dot_product(self%normal(:, w), x(:, i)) - self%offset(w)
                if (d >= self%d0) cycle
                write (msg, '(a,i0,a,g0.4,a,i0,a,g0.4,a,g0.4,a,g0.4,a,g0.4,a)') 'boundary node ', i, ' starts ', d, &
                    ' from wall ', w, ' (normal ', self%normal(1, w), ', ', self%normal(2, w), ', ', self%normal(3, w), &
                    '), within wall_distance = ', self%d0, ' or behind the wall: start the mesh further inside the walls'
                ok = .false.
                return
            end do
        end do
    end subroutine walls_check_start

    !> Local indices have changed: the owned boundary nodes, in local order.
    subroutine walls_on_rebuild(self, atoms)
        class(walls_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        integer :: i
        integer(i8) :: id
        call reserve(self%mine, atoms%nlocal, minimum=1, exact=.true.)
        self%nmine = 0
        do i = 1, atoms%nlocal
            id = atoms%id(i)
            if (id < 1 .or. id > size(self%boundary_of_id)) cycle
            if (.not. self%boundary_of_id(id)) cycle
            self%nmine = self%nmine + 1
            self%mine(self%nmine) = i
        end do
    end subroutine walls_on_rebuild

    subroutine walls_forces(self, atoms, list, halo, want_energy, energy, virial)
        class(walls_t), intent(inout) :: self
        include 'potential_forces_args.inc'
        integer :: m, i, w
        real(dp) :: dn, gap
        energy = 0; virial = 0
        do m = 1, self%nmine
            i = self%mine(m)
            do w = 1, self%nwall
                dn = self%normal(1, w)*atoms%x(1, i) + self%normal(2, w)*atoms%x(2, i) + self%normal(3, w)*atoms%x(3, i)
                gap = self%d0 - (dn - self%offset(w))
                if (gap <= 0) cycle
                atoms%f(:, i) = atoms%f(:, i) + (self%k*gap)*self%normal(:, w)
                energy = energy + 0.5_dp*self%k*gap*gap
                virial = virial + self%k*gap*dn
            end do
        end do
    end subroutine walls_forces

    !> (V, V', V'', W) of the owned boundary nodes at x + s v: d linear in s, exact.
    subroutine walls_ray(self, atoms, list, s, out)
        class(walls_t), intent(inout) :: self
        include 'potential_ray_args.inc'
        integer :: m, i, w
        real(dp) :: y(3), dn, d1, gap
        out = 0
        do m = 1, self%nmine
            i = self%mine(m)
            y = atoms%x(:, i) + s*atoms%v(:, i)
            do w = 1, self%nwall
                dn = self%normal(1, w)*y(1) + self%normal(2, w)*y(2) + self%normal(3, w)*y(3)
                gap = self%d0 - (dn - self%offset(w))
                if (gap <= 0) cycle
                d1 = self%normal(1, w)*atoms%v(1, i) + self%normal(2, w)*atoms%v(2, i) + self%normal(3, w)*atoms%v(3, i)
                out(1) = out(1) + 0.5_dp*self%k*gap*gap
                out(2) = out(2) - self%k*gap*d1
                out(3) = out(3) + self%k*d1*d1
                out(4) = out(4) + self%k*gap*dn
            end do
        end do
    end subroutine walls_ray

    !> No pairs: the walls act on single nodes.
    pure real(dp) function walls_cutoff(self)
        class(walls_t), intent(in) :: self
        walls_cutoff = 0
    end function walls_cutoff

    pure logical function walls_needs_pair_list(self)
        class(walls_t), intent(in) :: self
        walls_needs_pair_list = .false.
    end function walls_needs_pair_list

    !> tau with 0.005 tau = 1/(2 omega), omega^2 = k / m_min: the lightest boundary node on one wall's
    !> spring, at a quarter of Verlet's limit 2/omega (as contact's time scale, with one spring).
    pure subroutine walls_time_unit(self, mass, mvv2e, tau, words)
        class(walls_t), intent(in) :: self
        real(dp), intent(in) :: mass, mvv2e
        real(dp), intent(out) :: tau
        character(len=:), allocatable, intent(out) :: words
        tau = 0
        if (self%min_mass > 0 .and. self%k > 0) tau = 100*sqrt(self%min_mass/self%k)
        words = 'a quarter of Verlet''s limit on a wall''s spring'
    end subroutine walls_time_unit

    function walls_describe(self) result(text)
        class(walls_t), intent(in) :: self
        character(len=:), allocatable :: text
        character(len=400) :: s
        write (s, '(a,i0,a,i0,a,es11.4,a,es11.4,a,es11.4,a)') 'walls: ', self%nwall, ' planes against ', &
            self%nboundary, ' boundary nodes, k/2 (d0 - d)^2 with d the signed distance to the plane, k = ', self%k, &
            ', d0 = ', self%d0, ' (mean boundary edge ', self%spacing, ')'
        text = trim(s)
    end function walls_describe

end module terrace_walls
