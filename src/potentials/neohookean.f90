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
!>
!> Elements are given by the global ids of their nodes; each is computed once, on the rank that owns
!> its node of lowest id, after on_rebuild has mapped ids to this rank's local indices (owned or
!> ghost). Element arrays are structures of arrays; the kernels gather the four nodes, do the 3x3
!> arithmetic branch-free, and scatter.
module terrace_neohookean
    use terrace_kinds, only: dp, i8
    use terrace_vec3, only: cross
    use terrace_atoms, only: atoms_t
    use terrace_neighbor_list, only: neighbor_list_t
    use terrace_potential, only: potential_t, halo_ops_t
    implicit none
    private

    real(dp), parameter, public :: inverted_energy = 1.0e30_dp   !< wall height past an inversion, per V0 (lambda + mu)

    type, extends(potential_t), public :: neohookean_t
        real(dp) :: lambda = 0, mu = 0
        integer :: nelem = 0
        integer(i8), allocatable :: node(:, :)      !< (4, nelem) global node ids
        real(dp), allocatable :: dminv(:, :)        !< (9, nelem) Dm^-1, column major
        real(dp), allocatable :: v0(:)              !< reference volumes
        real(dp) :: reach = 0                       !< largest reference element extent (halo reach hint)
        real(dp) :: min_height = huge(1.0_dp)       !< smallest reference element altitude (stability)
        real(dp) :: density = 0                     !< mass density (for the wave speed; 0: unknown)
        ! after on_rebuild: the elements this rank computes and their nodes' local indices
        integer :: nmine = 0
        integer, allocatable :: mine(:)             !< element numbers
        integer, allocatable :: loc(:, :)           !< (4, nmine) local atom indices
        integer, allocatable :: id_map(:)           !< scratch: global id -> local index (0: not here)
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
        procedure :: time_scale => nh_time_scale
        procedure :: may_become_invalid => nh_may_become_invalid
        procedure :: invalid_state => nh_invalid_state
    end type neohookean_t

    public :: det3, inv3

contains

    !> Elements from node ids tets(4, ne) and the reference positions xref(3, id) of the nodes.
    !> ok = .false. with a message for a degenerate or inverted reference element.
    subroutine nh_setup(self, lambda, mu, tets, xref, ok, msg)
        class(neohookean_t), intent(inout) :: self
        real(dp), intent(in) :: lambda, mu
        integer(i8), intent(in) :: tets(:, :)
        real(dp), intent(in) :: xref(:, :)       !< (3, max id): reference position of node id
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        real(dp) :: dm(3, 3), minv(3, 3), det, size3
        integer :: e, a
        self%lambda = lambda; self%mu = mu
        self%nelem = size(tets, 2)
        allocate (self%node(4, self%nelem), self%dminv(9, self%nelem), self%v0(self%nelem))
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

    !> Map node ids to local indices and pick the elements whose lowest-id node this rank owns.
    subroutine nh_on_rebuild(self, atoms)
        class(neohookean_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        integer :: i, e, a, n, nall, low
        integer(i8) :: maxid
        nall = atoms%nall()
        maxid = maxval(self%node)
        if (allocated(self%id_map)) then
            if (size(self%id_map) < maxid) deallocate (self%id_map)
        end if
        if (.not. allocated(self%id_map)) allocate (self%id_map(maxid))
        self%id_map = 0
        ! owned atoms last, so that an owned copy wins over a periodic ghost image of the same id
        do i = nall, 1, -1
            if (atoms%id(i) >= 1 .and. atoms%id(i) <= maxid) self%id_map(atoms%id(i)) = i
        end do
        if (.not. allocated(self%mine)) allocate (self%mine(self%nelem), self%loc(4, self%nelem))
        n = 0
        self%missing_node = .false.
        do e = 1, self%nelem
            low = minloc(self%node(:, e), 1)
            i = self%id_map(self%node(low, e))
            if (i < 1 .or. i > atoms%nlocal) cycle
            n = n + 1
            self%mine(n) = e
            do a = 1, 4
                self%loc(a, n) = self%id_map(self%node(a, e))
                if (self%loc(a, n) == 0) self%missing_node = .true.
            end do
        end do
        self%nmine = n
    end subroutine nh_on_rebuild

    !> Forces, and the energy and virial (always computed: they cost nothing extra here).
    subroutine nh_forces(self, atoms, list, halo, want_energy, energy, virial)
        class(neohookean_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        type(neighbor_list_t), intent(in) :: list
        class(halo_ops_t), intent(inout) :: halo
        logical, intent(in) :: want_energy
        real(dp), intent(out) :: energy, virial
        integer :: k, e, a
        integer :: l(4)
        real(dp) :: ds(3, 3), f(3, 3), minv(3, 3), fit(3, 3), p(3, 3), h(3, 3), j, lnj, w
        energy = 0; virial = 0
        self%first_inverted = 0
        do k = 1, self%nmine
            e = self%mine(k)
            l = self%loc(:, k)
            do a = 1, 3
                ds(:, a) = atoms%x(:, l(a + 1)) - atoms%x(:, l(1))
            end do
            minv = reshape(self%dminv(:, e), [3, 3])
            f = matmul(ds, minv)
            j = det3(f)
            if (.not. (j > 0)) then
                if (self%first_inverted == 0) self%first_inverted = e
                cycle
            end if
            fit = transpose(inv3(f, j))
            lnj = log(j)
            p = self%mu*(f - fit) + self%lambda*lnj*fit
            h = -self%v0(e)*matmul(p, transpose(minv))
            do a = 1, 3
                atoms%f(:, l(a + 1)) = atoms%f(:, l(a + 1)) + h(:, a)
            end do
            atoms%f(:, l(1)) = atoms%f(:, l(1)) - (h(:, 1) + h(:, 2) + h(:, 3))
            w = 0.5_dp*self%lambda*lnj**2 - self%mu*lnj + 0.5_dp*self%mu*(sum(f*f) - 3)
            energy = energy + self%v0(e)*w
            virial = virial - self%v0(e)*(self%mu*(sum(f*f) - 3) + 3*self%lambda*lnj)
        end do
    end subroutine nh_forces

    !> (V, V', V'', W) of this rank's elements at x + s v.
    subroutine nh_ray(self, atoms, list, s, out)
        class(neohookean_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        type(neighbor_list_t), intent(in) :: list
        real(dp), intent(in) :: s
        real(dp), intent(out) :: out(4)
        integer :: k, e, a
        integer :: l(4)
        real(dp) :: ds(3, 3), dv(3, 3), minv(3, 3), f0(3, 3), g(3, 3), am(3, 3), j0, c1, c2, c3, pp, p1, p2, &
                    lnj, l1, l2, t0, fg, gg, trf, w, w1, w2
        out = 0
        do k = 1, self%nmine
            e = self%mine(k)
            l = self%loc(:, k)
            do a = 1, 3
                ds(:, a) = atoms%x(:, l(a + 1)) - atoms%x(:, l(1))
                dv(:, a) = atoms%v(:, l(a + 1)) - atoms%v(:, l(1))
            end do
            minv = reshape(self%dminv(:, e), [3, 3])
            f0 = matmul(ds, minv)
            g = matmul(dv, minv)
            j0 = det3(f0)
            if (.not. (j0 > 0)) then
                out(1) = out(1) + inverted_energy*self%v0(e)*(self%lambda + self%mu)
                cycle
            end if
            am = matmul(inv3(f0, j0), g)
            c1 = am(1, 1) + am(2, 2) + am(3, 3)
            c2 = 0.5_dp*(c1*c1 - sum(am*transpose(am)))
            c3 = det3(am)
            pp = 1 + s*(c1 + s*(c2 + s*c3))
            if (.not. (pp > 0)) then
                ! beyond the inversion of this element: an energy wall the search cannot pass
                out(1) = out(1) + inverted_energy*self%v0(e)*(self%lambda + self%mu)*(1 + abs(s))
                cycle
            end if
            p1 = c1 + s*(2*c2 + 3*s*c3)
            p2 = 2*c2 + 6*s*c3
            lnj = log(j0) + log(pp)
            l1 = p1/pp
            l2 = p2/pp - l1*l1
            t0 = sum(f0*f0); fg = sum(f0*g); gg = sum(g*g)
            trf = t0 + 2*s*fg + s*s*gg
            w = 0.5_dp*self%lambda*lnj**2 - self%mu*lnj + 0.5_dp*self%mu*(trf - 3)
            w1 = (self%lambda*lnj - self%mu)*l1 + self%mu*(fg + s*gg)
            w2 = self%lambda*l1*l1 + (self%lambda*lnj - self%mu)*l2 + self%mu*gg
            out(1) = out(1) + self%v0(e)*w
            out(2) = out(2) + self%v0(e)*w1
            out(3) = out(3) + self%v0(e)*w2
            out(4) = out(4) - self%v0(e)*(self%mu*(trf - 3) + 3*self%lambda*lnj)
        end do
    end subroutine nh_ray

    !> The engine prints 0.005 tau as a stable velocity-Verlet step: tau = 100 l_min / c_d makes that
    !> l_min / (2 c_d), half the element's dilatational transit time (c_d = sqrt((lambda + 2 mu)/rho)).
    pure real(dp) function nh_time_scale(self, mass, mvv2e)
        class(neohookean_t), intent(in) :: self
        real(dp), intent(in) :: mass, mvv2e
        nh_time_scale = 0
        if (self%density > 0) nh_time_scale = 100*self%min_height/sqrt((self%lambda + 2*self%mu)/self%density)
    end function nh_time_scale


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
                self%node(:, self%first_inverted), ') turned inside out (J <= 0): the time step is too large for '// &
                'this mesh and material (see the stability estimate), or the deformation is beyond the mesh'
            bad = .true.
        else if (self%missing_node) then
            text = 'an element''s node is not among this rank''s atoms (the halo is too short for the deformation)'
            bad = .true.
        end if
    end function nh_invalid_state

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
        write (s, '(a,i0,a,es11.4,a,es11.4,a)') 'neohookean, ', self%nelem, ' tetrahedra, lambda = ', self%lambda, &
            ', mu = ', self%mu, '; no pair list, no density pass'
        text = trim(s)
    end function nh_describe

end module terrace_neohookean
