!> 3-D Cartesian domain decomposition: ownership, migration, halo (ghost) exchange and the
!> reverse sum of ghost forces.
!>
!> The box is cut into dims(1) x dims(2) x dims(3) equal bricks (MPI_Dims_create, MPI_Cart_create);
!> rank (c1,c2,c3) owns the atoms with floor((x_d - lo_d) P_d / L_d) = c_d (clamped at free edges,
!> so atoms that leave a free box stay with the outermost rank).
!>
!> Halo ("borders"): for d = x, y, z in turn, and for as many hops as the ghost cutoff needs,
!> atoms within cutghost of the lower face go to the lower neighbour and those within cutghost of
!> the upper face to the upper one; ghosts received in earlier dimensions travel on, which fills
!> edges and corners. Crossing a periodic face adds -/+ L_d to the copy. With one rank along a
!> periodic dimension the "neighbour" is the rank itself and the swap is a plain copy: a one-rank
!> run makes no MPI call at all; there, where a half list is all that reads the ghosts, the halo
!> can instead hold half the images (half_images). Pairs are counted once (Newton's third law across ghosts):
!> forces accumulated on ghosts are sent back along the same swaps in reverse order and added.
module terrace_domain
    use terrace_kinds, only: dp, i8
    use terrace_box, only: box_t
    use terrace_atoms, only: atoms_t, clock_unset
    use terrace_mpi_env, only: world, any_all
    use terrace_errors, only: check_all
    use terrace_grow, only: reserve
    use mpi_f08, only: MPI_Comm, MPI_Dims_create, MPI_Cart_create, MPI_Cart_coords, MPI_Cart_shift, &
                       MPI_Comm_rank, MPI_Sendrecv, MPI_DOUBLE_PRECISION, MPI_INTEGER, MPI_STATUS_IGNORE, &
                       MPI_PROC_NULL, MPI_Request, MPI_Irecv, MPI_Isend, MPI_Waitall, MPI_STATUSES_IGNORE, &
                       MPI_F_sync_reg
    implicit none
    private

    type :: swap_t
        integer :: dim = 1
        integer :: send_to = MPI_PROC_NULL
        integer :: recv_from = MPI_PROC_NULL
        logical :: self_copy = .false.
        !> this swap and the next travel together (domain_forward, domain_reverse): the two directions
        !> of one hop along a divided dimension
        logical :: with_next = .false.
        integer :: dir = 1
        real(dp) :: shift(3) = 0
        integer :: nsend = 0, nrecv = 0, first_recv = 0
        integer, allocatable :: list(:)
    end type swap_t

    type, public :: domain_t
        type(MPI_Comm) :: cart
        integer :: dims(3) = 1, coords(3) = 0
        integer :: nbr_lo(3) = -1, nbr_hi(3) = -1
        real(dp) :: sublo(3) = 0, subhi(3) = 0
        real(dp) :: cutghost = 0
        !> .false.: no ghosts below the brick along z in 3-D. The half neighbour list pairs an owned
        !> atom with a ghost only if the ghost is above it in (z, y, x) order, and every ghost below
        !> the brick is below every owned atom: where the potential's passes read that list and
        !> nothing else (the engine decides), those ghosts are never read. Without them the list,
        !> the forces and their order are the same, and the halo is a quarter smaller on one rank.
        logical :: ghosts_below = .true.
        !> .true. (with ghosts_below .false.: the engine asks for it where the half list is all that
        !> reads the ghosts): where this rank is alone along every dimension of a 3-D box and the
        !> ghost cutoff is shorter than every periodic edge, the halo holds the images of the owned
        !> atoms under the 13 "positive" periodic shifts only (S_z > 0; or S_z = 0, S_y > 0; or
        !> S = (1, 0, 0)), those within cutghost of the box; halved (set by borders) says it did.
        !> Each pair of an atom and another atom's image (or its own) is then an owned atom with a
        !> ghost exactly once, so that the list pairs every owned atom with every ghost within the
        !> cutoff (neighbor_list_t%half_images); half the ghost shell, one pass over the atoms.
        logical :: half_images = .false.
        logical :: halved = .false.
        integer, allocatable :: edge(:, :)           !< half_image_borders' scratch: the atoms near each face
        integer :: nedge(2, 3) = 0                  !< (side, d): lengths of edge(:, 2 d - 2 + side)
        integer :: nswap = 0
        type(swap_t), allocatable :: swaps(:)
        real(dp), allocatable :: sendbuf(:), recvbuf(:)
        type(box_t) :: box
    contains
        procedure :: setup => domain_setup
        procedure :: resize => domain_resize
        procedure :: owner_coord => domain_owner_coord
        procedure :: owns => domain_owns
        procedure :: wrap => domain_wrap
        procedure :: migrate => domain_migrate
        procedure :: borders => domain_borders
        procedure :: forward => domain_forward
        procedure :: forward_xv => domain_forward_xv
        procedure :: reverse => domain_reverse
        procedure :: image_owners => domain_image_owners
    end type domain_t

    integer, parameter :: migrate_width = 12   ! x(3) v(3) type id image(3) clock
    integer, parameter :: border_width = 8     ! x(3) v(3) type id (ids: terms with fixed partners, e.g. mesh elements)

contains

    !> Choose the processor grid and this rank's brick. The factors from MPI_Dims_create are
    !> assigned largest to the longest box edge; grid (a restart: the interrupted run's grid, which
    !> an anisotropic barostat's box may no longer give) is taken instead when it fits the ranks.
    subroutine domain_setup(self, box, cutghost, grid)
        class(domain_t), intent(inout) :: self
        type(box_t), intent(in) :: box
        real(dp), intent(in) :: cutghost
        integer, intent(in), optional :: grid(3)
        integer :: dims(3), nd, d, k, order(3), tmp
        logical :: periods(3)
        real(dp) :: len_sorted(3)
        self%box = box
        self%cutghost = cutghost
        nd = box%dimension
        dims = 0
        if (nd == 2) dims(3) = 1
        call MPI_Dims_create(world%nprocs, 3, dims)
        ! sort factors descending, assign to edges by descending length
        do d = 1, 2
            do k = d + 1, 3
                if (dims(k) > dims(d)) then
                    tmp = dims(d); dims(d) = dims(k); dims(k) = tmp
                end if
            end do
        end do
        order = [1, 2, 3]
        len_sorted = box%length
        if (nd == 2) len_sorted(3) = -1
        do d = 1, 2
            do k = d + 1, 3
                if (len_sorted(order(k)) > len_sorted(order(d))) then
                    tmp = order(d); order(d) = order(k); order(k) = tmp
                end if
            end do
        end do
        do d = 1, 3
            self%dims(order(d)) = dims(d)
        end do
        if (present(grid)) then
            if (product(grid) == world%nprocs .and. all(grid >= 1) .and. (nd == 3 .or. grid(3) == 1)) self%dims = grid
        end if
        periods = box%periodic
        call MPI_Cart_create(world%comm, 3, self%dims, periods, .false., self%cart)
        call MPI_Comm_rank(self%cart, k)
        call MPI_Cart_coords(self%cart, k, 3, self%coords)
        do d = 1, 3
            call MPI_Cart_shift(self%cart, d - 1, 1, self%nbr_lo(d), self%nbr_hi(d))
            self%sublo(d) = box%lo(d) + self%coords(d)*box%length(d)/self%dims(d)
            self%subhi(d) = box%lo(d) + (self%coords(d) + 1)*box%length(d)/self%dims(d)
            if (self%coords(d) == self%dims(d) - 1) self%subhi(d) = box%hi(d)
        end do
    end subroutine domain_setup

    !> The same processor grid over a box of new extent (a barostat's or a box relaxation's
    !> change): the box, this rank's brick and the halo's periodic shifts; no communication. The
    !> caller migrates and rebuilds the halo next (borders reads the box and the brick), or keeps
    !> the halo and refreshes the ghosts.
    subroutine domain_resize(self, box)
        class(domain_t), intent(inout) :: self
        type(box_t), intent(in) :: box
        integer :: d
        integer :: k
        self%box = box
        do d = 1, 3
            self%sublo(d) = box%lo(d) + self%coords(d)*box%length(d)/self%dims(d)
            self%subhi(d) = box%lo(d) + (self%coords(d) + 1)*box%length(d)/self%dims(d)
            if (self%coords(d) == self%dims(d) - 1) self%subhi(d) = box%hi(d)
        end do
        ! the halo's periodic shifts follow the box (a halo kept until the next build: a forward
        ! refresh places the ghosts at their owners' images in the new box)
        if (allocated(self%swaps)) then
            do k = 1, size(self%swaps)
                do d = 1, 3
                    if (self%swaps(k)%shift(d) /= 0) self%swaps(k)%shift(d) = sign(box%length(d), self%swaps(k)%shift(d))
                end do
            end do
        end if
    end subroutine domain_resize

    pure integer function domain_owner_coord(self, d, xd) result(c)
        class(domain_t), intent(in) :: self
        integer, intent(in) :: d
        real(dp), intent(in) :: xd
        c = int(floor((xd - self%box%lo(d))*self%dims(d)/self%box%length(d)))
        c = min(self%dims(d) - 1, max(0, c))
    end function domain_owner_coord

    pure logical function domain_owns(self, x)
        class(domain_t), intent(in) :: self
        real(dp), intent(in) :: x(3)
        integer :: d
        domain_owns = .true.
        do d = 1, self%box%dimension
            if (self%owner_coord(d, x(d)) /= self%coords(d)) domain_owns = .false.
        end do
    end function domain_owns

    !> Wrap owned atoms back into the periodic box, counting the crossings in the image flags.
    subroutine domain_wrap(self, atoms)
        class(domain_t), intent(in) :: self
        type(atoms_t), intent(inout) :: atoms
        integer :: i, d
        do d = 1, self%box%dimension
            if (.not. self%box%periodic(d)) cycle
            do i = 1, atoms%nlocal
                if (atoms%x(d, i) < self%box%lo(d)) then
                    atoms%x(d, i) = atoms%x(d, i) + self%box%length(d)
                    atoms%image(d, i) = atoms%image(d, i) - 1
                    if (atoms%x(d, i) >= self%box%hi(d)) atoms%x(d, i) = self%box%lo(d)
                else if (atoms%x(d, i) >= self%box%hi(d)) then
                    atoms%x(d, i) = atoms%x(d, i) - self%box%length(d)
                    atoms%image(d, i) = atoms%image(d, i) + 1
                    if (atoms%x(d, i) < self%box%lo(d)) atoms%x(d, i) = self%box%lo(d)
                end if
            end do
        end do
    end subroutine domain_wrap

    !> Send owned atoms that left this brick to the neighbour in that direction, one dimension at
    !> a time, repeating until no atom anywhere is misplaced along that dimension.
    subroutine domain_migrate(self, atoms)
        class(domain_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        integer :: d, i, dir, nsend(2), nrecv(2), delta, p
        logical :: misplaced
        atoms%nghost = 0
        call check_reach(self, atoms)
        call self%wrap(atoms)
        if (world%nprocs == 1) return
        do d = 1, self%box%dimension
            if (self%dims(d) == 1) cycle
            do
                nsend = 0
                ! pack leavers: first the ones going down, then the ones going up
                call reserve(self%sendbuf, migrate_width*atoms%nlocal, minimum=1024)
                do dir = 1, 2
                    i = 1
                    do while (i <= atoms%nlocal)
                        delta = step_of(self, d, atoms%x(d, i))
                        if ((dir == 1 .and. delta < 0) .or. (dir == 2 .and. delta > 0)) then
                            p = migrate_width*(nsend(1) + nsend(2))
                            call pack_atom(atoms, i, self%sendbuf(p + 1:p + migrate_width))
                            nsend(dir) = nsend(dir) + 1
                            call atoms%copy_owned(atoms%nlocal, i)
                            atoms%nlocal = atoms%nlocal - 1
                        else
                            i = i + 1
                        end if
                    end do
                end do
                ! down-going to nbr_lo, receive from nbr_hi; then up-going
                call MPI_Sendrecv(nsend(1), 1, MPI_INTEGER, self%nbr_lo(d), 1, nrecv(1), 1, MPI_INTEGER, &
                                  self%nbr_hi(d), 1, self%cart, MPI_STATUS_IGNORE)
                call MPI_Sendrecv(nsend(2), 1, MPI_INTEGER, self%nbr_hi(d), 2, nrecv(2), 1, MPI_INTEGER, &
                                  self%nbr_lo(d), 2, self%cart, MPI_STATUS_IGNORE)
                if (self%nbr_hi(d) == MPI_PROC_NULL) nrecv(1) = 0
                if (self%nbr_lo(d) == MPI_PROC_NULL) nrecv(2) = 0
                call reserve(self%recvbuf, migrate_width*(nrecv(1) + nrecv(2)), minimum=1024)
                call MPI_Sendrecv(self%sendbuf, migrate_width*nsend(1), MPI_DOUBLE_PRECISION, self%nbr_lo(d), 3, &
                                  self%recvbuf, migrate_width*nrecv(1), MPI_DOUBLE_PRECISION, self%nbr_hi(d), 3, &
                                  self%cart, MPI_STATUS_IGNORE)
                call MPI_Sendrecv(self%sendbuf(migrate_width*nsend(1) + 1:), migrate_width*nsend(2), &
                                  MPI_DOUBLE_PRECISION, self%nbr_hi(d), 4, &
                                  self%recvbuf(migrate_width*nrecv(1) + 1:), migrate_width*nrecv(2), &
                                  MPI_DOUBLE_PRECISION, self%nbr_lo(d), 4, self%cart, MPI_STATUS_IGNORE)
                call atoms%reserve(atoms%nlocal + nrecv(1) + nrecv(2))
                do i = 1, nrecv(1) + nrecv(2)
                    p = migrate_width*(i - 1)
                    call unpack_atom(atoms, self%recvbuf(p + 1:p + migrate_width))
                end do
                misplaced = .false.
                do i = 1, atoms%nlocal
                    if (step_of(self, d, atoms%x(d, i)) /= 0) misplaced = .true.
                end do
                call any_all(misplaced)
                if (.not. misplaced) exit
            end do
        end do
    end subroutine domain_migrate

    !> Failure detection (collective): a non-finite coordinate, or an atom more than one box length
    !> outside a periodic box (it moved that far since the last build; wrap would then misplace it),
    !> means the run has blown up. Stops every rank with one line naming the atom.
    subroutine check_reach(self, atoms)
        type(domain_t), intent(in) :: self
        type(atoms_t), intent(in) :: atoms
        integer :: i, d
        logical :: ok, bad
        character(len=320) :: msg
        character(len=1), parameter :: axis(3) = ['x', 'y', 'z']
        ok = .true.
        msg = ''
        outer: do i = 1, atoms%nlocal
            do d = 1, self%box%dimension
                if (.not. (abs(atoms%x(d, i)) <= huge(1.0_dp))) then
                    write (msg, '(a,i0,a)') 'atom ', atoms%id(i), ' has a non-finite position (NaN or infinity): '// &
                        'the run is unstable (time step or terrace height too large, or atoms overlapping)'
                    ok = .false.
                    exit outer
                end if
                if (.not. self%box%periodic(d)) cycle
                if (atoms%x(d, i) < self%box%lo(d) - self%box%length(d) .or. &
                    atoms%x(d, i) >= self%box%hi(d) + self%box%length(d)) then
                    write (msg, '(a,i0,a,a,a,es11.4,a)') 'atom ', atoms%id(i), ' moved more than one box length along ', &
                        axis(d), ' since the last neighbour-list build (x = ', atoms%x(d, i), &
                        '): the run is unstable (time step too large, or atoms overlapping)'
                    ok = .false.
                    exit outer
                end if
            end do
        end do outer
        ! agree over the domain's communicator first (world: a test may run on a sub-communicator);
        ! only a failure goes through the error path's collective stop
        bad = .not. ok
        call any_all(bad)
        if (bad) call check_all(ok, trim(msg))
    end subroutine check_reach

    !> Signed number of bricks from this rank to the owner along d (shortest way round when periodic).
    pure integer function step_of(self, d, xd) result(delta)
        type(domain_t), intent(in) :: self
        integer, intent(in) :: d
        real(dp), intent(in) :: xd
        integer :: p
        p = self%dims(d)
        delta = self%owner_coord(d, xd) - self%coords(d)
        if (self%box%periodic(d)) then
            if (delta > p/2) delta = delta - p
            if (delta < -(p - 1)/2) delta = delta + p
        end if
    end function step_of

    subroutine pack_atom(atoms, i, buf)
        type(atoms_t), intent(in) :: atoms
        integer, intent(in) :: i
        real(dp), intent(out) :: buf(:)
        buf(1:3) = atoms%x(:, i); buf(4:6) = atoms%v(:, i)
        buf(7) = real(atoms%type(i), dp)
        buf(8) = transfer(atoms%id(i), 1.0_dp)
        buf(9:11) = real(atoms%image(:, i), dp)
        buf(12) = clock_unset
        if (allocated(atoms%clock)) buf(12) = atoms%clock(i)
    end subroutine pack_atom

    subroutine unpack_atom(atoms, buf)
        type(atoms_t), intent(inout) :: atoms
        real(dp), intent(in) :: buf(:)
        integer :: n
        n = atoms%nlocal + 1
        atoms%x(:, n) = buf(1:3); atoms%v(:, n) = buf(4:6); atoms%f(:, n) = 0
        atoms%type(n) = nint(buf(7))
        atoms%id(n) = transfer(buf(8), 1_i8)
        atoms%image(:, n) = nint(buf(9:11))
        if (allocated(atoms%clock)) atoms%clock(n) = buf(12)
        atoms%nlocal = n
    end subroutine unpack_atom

    !> Where every ghost is a periodic image of an owned atom of this rank (every swap of the halo a
    !> copy within the rank), owner(j) = the owned atom that ghost j copies (j for an owned atom),
    !> for the atoms held; otherwise .false. and owner untouched.
    logical function domain_image_owners(self, atoms, owner) result(ok)
        class(domain_t), intent(in) :: self
        type(atoms_t), intent(in) :: atoms
        integer, allocatable, intent(inout) :: owner(:)
        integer :: s, j, i
        ok = .true.
        if (self%nswap > 0) ok = all(self%swaps(1:self%nswap)%self_copy)
        if (.not. ok) return
        call reserve(owner, atoms%nlocal + atoms%nghost)
        do i = 1, atoms%nlocal
            owner(i) = i
        end do
        do s = 1, self%nswap
            associate (sw => self%swaps(s))
                do j = 1, sw%nsend
                    owner(sw%first_recv + j - 1) = owner(sw%list(j))
                end do
            end associate
        end do
    end function domain_image_owners

    !> Build the ghost layer and remember every swap for forward and reverse communication.
    subroutine domain_borders(self, atoms)
        class(domain_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        integer :: d, hop, nhop, dir, nfirst, cand_lo, cand_hi, s
        integer :: prev(2)
        real(dp) :: width, lim
        atoms%nghost = 0
        self%nswap = 0
        if (.not. allocated(self%swaps)) allocate (self%swaps(6))
        self%halved = self%half_images .and. .not. self%ghosts_below .and. self%box%dimension == 3 .and. &
                      all(self%dims == 1)
        if (self%halved) self%halved = all(.not. self%box%periodic .or. self%cutghost < self%box%length)
        if (self%halved) then
            call half_image_borders(self, atoms)
            return
        end if
        do d = 1, self%box%dimension
            if (self%dims(d) == 1 .and. .not. self%box%periodic(d)) cycle
            width = self%box%length(d)/self%dims(d)
            nhop = max(1, ceiling(self%cutghost/width))
            if (self%box%periodic(d)) then
                nhop = min(nhop, self%dims(d))
            else
                nhop = min(nhop, self%dims(d) - 1)
            end if
            nfirst = atoms%nlocal + atoms%nghost
            prev = 0
            do hop = 1, nhop
                do dir = 1, 2
                    ! (dir 2 sends up: the receiver's ghosts below it)
                    if (dir == 2 .and. d == 3 .and. .not. self%ghosts_below) cycle
                    call add_swap(self, d, dir)
                    s = self%nswap
                    ! the hop's swap down and this one up travel together in forward and reverse
                    if (dir == 2 .and. .not. self%swaps(s)%self_copy) &
                        self%swaps(s - 1)%with_next = prev(1) == s - 1
                    if (hop == 1) then
                        cand_lo = 1; cand_hi = nfirst
                    else
                        cand_lo = self%swaps(prev(dir))%first_recv
                        cand_hi = cand_lo + self%swaps(prev(dir))%nrecv - 1
                    end if
                    if (dir == 1) then
                        lim = self%sublo(d) + self%cutghost
                    else
                        lim = self%subhi(d) - self%cutghost
                    end if
                    call select_borders(self%swaps(s), atoms, dir, lim, cand_lo, cand_hi)
                    call exchange_borders(self%swaps(s), atoms, self%cart, self%sendbuf, self%recvbuf)
                    prev(dir) = s
                end do
            end do
        end do
    end subroutine domain_borders

    !> The halo of half_images: one swap (a copy) per positive shift S, the owned atoms whose image
    !> under S lies within cutghost of the box (for a face's shift x_d < lo_d + cutghost where S_d =
    !> 1, x_d >= hi_d - cutghost where S_d = -1; for an edge's or a corner's the distance from the
    !> edge or corner). The atoms near each face are listed in one pass over the atoms; an edge's or
    !> a corner's candidates are those of (0, S_y, S_z) where that shift has a swap, else the shorter
    !> list of its two faces.
    subroutine half_image_borders(self, atoms)
        class(domain_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        integer :: d, n, sx, sy, sz, s(3), k, best, ns, e, parent, i
        real(dp) :: lo(3), hi(3)
        n = atoms%nlocal
        if (allocated(self%edge)) then
            if (size(self%edge, 1) < n + 1) deallocate (self%edge)
        end if
        if (.not. allocated(self%edge)) allocate (self%edge(max(n + 1, 64), 6))
        ! edge(:, 2 d - 2 + side): the atoms within cutghost of the lower (side 1) or upper (2) face
        ! along a periodic d
        lo = self%box%lo + self%cutghost
        hi = self%box%hi - self%cutghost
        self%nedge = 0
        do d = 1, 3
            if (.not. self%box%periodic(d)) cycle
            call near_faces(atoms%x, n, d, lo(d), hi(d), self%edge(:, 2*d - 1), self%edge(:, 2*d), &
                            self%nedge(1, d), self%nedge(2, d))
        end do
        do sz = 0, 1
            do sy = -1, 1
                parent = 0
                do i = 1, 3
                    sx = merge(0, merge(-1, 1, i == 2), i == 1)    ! sx = 0 first: the parent of +-1
                    s = [sx, sy, sz]
                    if (.not. (sz > 0 .or. (sz == 0 .and. sy > 0) .or. (sz == 0 .and. sy == 0 .and. sx > 0))) cycle
                    if (any(s /= 0 .and. .not. self%box%periodic)) cycle
                    call add_image_swap(self, s)
                    associate (sw => self%swaps(self%nswap))
                        if (count(s /= 0) == 1) then
                            ! a face's images: the atoms near the face
                            d = maxloc(abs(s), 1)
                            k = merge(1, 2, s(d) > 0)
                            call take_list(sw%list, self%edge(:, 2*d - 2 + k), self%nedge(k, d), ns)
                        else if (sx /= 0 .and. parent > 0) then
                            ! an edge's or a corner's images: among those of (0, sy, sz), each tested
                            associate (pl => self%swaps(parent))
                                call within_reach(atoms%x, s, self%box%lo, self%box%hi, self%cutghost, pl%list, &
                                                  pl%nsend, sw%list, ns)
                            end associate
                        else
                            ! an edge's images: the shorter of its two faces' lists, each tested
                            best = 0
                            do d = 1, 3
                                if (s(d) == 0) cycle
                                k = merge(1, 2, s(d) > 0)
                                if (best == 0) then
                                    best = 2*d - 2 + k
                                else if (self%nedge(k, d) < self%nedge(2 - mod(best, 2), (best + 1)/2)) then
                                    best = 2*d - 2 + k
                                end if
                            end do
                            e = self%nedge(2 - mod(best, 2), (best + 1)/2)
                            call within_reach(atoms%x, s, self%box%lo, self%box%hi, self%cutghost, &
                                              self%edge(:, best), e, sw%list, ns)
                        end if
                        if (sx == 0) parent = self%nswap
                        sw%nsend = ns
                        sw%nrecv = ns
                        sw%first_recv = atoms%nlocal + atoms%nghost + 1
                        call atoms%reserve(atoms%nlocal + atoms%nghost + ns)
                        call copy_images(atoms%x, atoms%v, atoms%type, atoms%id, sw%list, ns, sw%first_recv, &
                                         sw%shift)
                        atoms%nghost = atoms%nghost + ns
                    end associate
                end do
            end do
        end do
    end subroutine half_image_borders

    !> The atoms 1..n within reach of the faces along d: x_d < lo into near_lo(1:nlo), x_d >= hi
    !> into near_hi(1:nhi).
    subroutine near_faces(x, n, d, lo, hi, near_lo, near_hi, nlo, nhi)
        integer, intent(in) :: n, d
        real(dp), intent(in) :: x(3, *), lo, hi
        integer, intent(inout) :: near_lo(*), near_hi(*)
        integer, intent(out) :: nlo, nhi
        integer :: i
        nlo = 0; nhi = 0
        do i = 1, n
            near_lo(nlo + 1) = i
            near_hi(nhi + 1) = i
            if (x(d, i) < lo) nlo = nlo + 1
            if (x(d, i) >= hi) nhi = nhi + 1
        end do
    end subroutine near_faces

    !> list(1:n) = candidates(1:n), list grown as needed.
    subroutine take_list(list, candidates, n, ns)
        integer, allocatable, intent(inout) :: list(:)
        integer, intent(in) :: candidates(:), n
        integer, intent(out) :: ns
        if (size(list) < n) then
            deallocate (list); allocate (list(n))
        end if
        list(1:n) = candidates(1:n)
        ns = n
    end subroutine take_list

    !> list(1:ns): the atoms of candidates(1:n) (near one of the faces that s crosses) whose image
    !> under s (an edge's or a corner's shift) lies within cutghost of the box: the sum over the
    !> shifted dimensions of the squared distances from the faces they cross below cutghost^2 (which
    !> implies that each is near its face).
    subroutine within_reach(x, s, lo, hi, cut, candidates, n, list, ns)
        real(dp), intent(in) :: x(3, *), lo(3), hi(3), cut
        integer, intent(in) :: s(3), n, candidates(:)
        integer, allocatable, intent(inout) :: list(:)
        integer, intent(out) :: ns
        integer :: k, i, d, d1, d2
        real(dp) :: r2, w1, w2, w3, o(3), c2
        if (size(list) < n) then
            deallocate (list); allocate (list(n))
        end if
        ! distance from the face crossed: |x_d - lo_d| (s_d = 1) or |x_d - hi_d| (s_d = -1)
        do d = 1, 3
            o(d) = merge(lo(d), hi(d), s(d) >= 0)
        end do
        c2 = cut*cut
        ns = 0
        if (all(s /= 0)) then
            do k = 1, n
                i = candidates(k)
                w1 = x(1, i) - o(1); w2 = x(2, i) - o(2); w3 = x(3, i) - o(3)
                r2 = w1*w1 + w2*w2 + w3*w3
                list(ns + 1) = i
                if (r2 < c2) ns = ns + 1
            end do
        else
            d1 = merge(1, 2, s(1) /= 0)
            d2 = merge(3, 2, s(3) /= 0)
            do k = 1, n
                i = candidates(k)
                w1 = x(d1, i) - o(d1); w2 = x(d2, i) - o(d2)
                r2 = w1*w1 + w2*w2
                list(ns + 1) = i
                if (r2 < c2) ns = ns + 1
            end do
        end if
    end subroutine within_reach

    !> Atoms list(1:n) copied into slots first.. as images under shift (positions, velocities,
    !> types, ids).
    subroutine copy_images(x, v, type, id, list, n, first, shift)
        real(dp), intent(inout) :: x(3, *), v(3, *)
        integer, intent(inout) :: type(*)
        integer(i8), intent(inout) :: id(*)
        integer, intent(in) :: n, list(n), first
        real(dp), intent(in) :: shift(3)
        integer :: k, i, j
        do k = 1, n
            i = list(k); j = first + k - 1
            x(1, j) = x(1, i) + shift(1); x(2, j) = x(2, i) + shift(2); x(3, j) = x(3, i) + shift(3)
            v(1, j) = v(1, i); v(2, j) = v(2, i); v(3, j) = v(3, i)
            type(j) = type(i)
            id(j) = id(i)
        end do
    end subroutine copy_images

    !> nswap one more, the swaps grown as needed.
    subroutine next_swap(self)
        class(domain_t), intent(inout) :: self
        type(swap_t), allocatable :: grown(:)
        if (self%nswap == size(self%swaps)) then
            allocate (grown(2*self%nswap))
            grown(1:self%nswap) = self%swaps
            call move_alloc(grown, self%swaps)
        end if
        self%nswap = self%nswap + 1
    end subroutine next_swap

    !> One more swap of half_image_borders: a copy within the rank under the periodic shift s.
    subroutine add_image_swap(self, s)
        class(domain_t), intent(inout) :: self
        integer, intent(in) :: s(3)
        integer :: d
        call next_swap(self)
        associate (sw => self%swaps(self%nswap))
            sw%dim = maxloc(abs(s), 1)
            sw%self_copy = .true.
            sw%with_next = .false.; sw%dir = 1
            sw%send_to = MPI_PROC_NULL; sw%recv_from = MPI_PROC_NULL
            do d = 1, 3
                sw%shift(d) = s(d)*self%box%length(d)
            end do
            if (.not. allocated(sw%list)) allocate (sw%list(64))
        end associate
    end subroutine add_image_swap

    !> One more swap along dimension d: dir 1 sends down (to nbr_lo) and receives from above, dir 2
    !> the other way; a periodic image crossing the box's edge is shifted by the box length.
    subroutine add_swap(self, d, dir)
        class(domain_t), intent(inout) :: self
        integer, intent(in) :: d, dir
        call next_swap(self)
        associate (sw => self%swaps(self%nswap))
            sw%dim = d
            sw%self_copy = self%dims(d) == 1
            sw%with_next = .false.; sw%dir = dir
            sw%shift = 0
            if (dir == 1) then
                sw%send_to = self%nbr_lo(d); sw%recv_from = self%nbr_hi(d)
                if (self%box%periodic(d) .and. self%coords(d) == 0) sw%shift(d) = self%box%length(d)
            else
                sw%send_to = self%nbr_hi(d); sw%recv_from = self%nbr_lo(d)
                if (self%box%periodic(d) .and. self%coords(d) == self%dims(d) - 1) &
                    sw%shift(d) = -self%box%length(d)
            end if
        end associate
    end subroutine add_swap

    !> The atoms cand_lo..cand_hi within the ghost cutoff of the face the swap sends across
    !> (dir 1: x < lim, the lower face; dir 2: x >= lim, the upper one) into sw%list(1:nsend).
    subroutine select_borders(sw, atoms, dir, lim, cand_lo, cand_hi)
        type(swap_t), intent(inout) :: sw
        type(atoms_t), intent(in) :: atoms
        integer, intent(in) :: dir, cand_lo, cand_hi
        real(dp), intent(in) :: lim
        integer :: i, ns, d
        d = sw%dim
        if (.not. allocated(sw%list)) allocate (sw%list(max(64, cand_hi - cand_lo + 1)))
        if (size(sw%list) < cand_hi - cand_lo + 1) then
            deallocate (sw%list); allocate (sw%list(cand_hi - cand_lo + 1))
        end if
        ns = 0
        if (sw%send_to /= MPI_PROC_NULL) then
            if (dir == 1) then
                do i = cand_lo, cand_hi
                    if (atoms%x(d, i) < lim) then
                        ns = ns + 1; sw%list(ns) = i
                    end if
                end do
            else
                do i = cand_lo, cand_hi
                    if (atoms%x(d, i) >= lim) then
                        ns = ns + 1; sw%list(ns) = i
                    end if
                end do
            end if
        end if
        sw%nsend = ns
    end subroutine select_borders

    !> The swap's selected atoms (x shifted, v, type, id) sent, and as many received appended as
    !> ghosts (a copy within the rank when the domain is alone along the dimension).
    subroutine exchange_borders(sw, atoms, cart, sendbuf, recvbuf)
        type(swap_t), intent(inout) :: sw
        type(atoms_t), intent(inout) :: atoms
        type(MPI_Comm), intent(in) :: cart
        real(dp), allocatable, intent(inout) :: sendbuf(:), recvbuf(:)
        integer :: i, j, n, p, ns
        ns = sw%nsend
        if (sw%self_copy) then
            sw%nrecv = ns
        else
            call MPI_Sendrecv(ns, 1, MPI_INTEGER, sw%send_to, 10, sw%nrecv, 1, MPI_INTEGER, &
                              sw%recv_from, 10, cart, MPI_STATUS_IGNORE)
            if (sw%recv_from == MPI_PROC_NULL) sw%nrecv = 0
        end if
        sw%first_recv = atoms%nlocal + atoms%nghost + 1
        call atoms%reserve(atoms%nlocal + atoms%nghost + sw%nrecv)
        if (sw%self_copy) then
            do j = 1, ns
                i = sw%list(j); n = sw%first_recv + j - 1
                atoms%x(:, n) = atoms%x(:, i) + sw%shift
                atoms%v(:, n) = atoms%v(:, i)
                atoms%type(n) = atoms%type(i)
                atoms%id(n) = atoms%id(i)
            end do
        else
            call reserve(sendbuf, border_width*ns, minimum=1024)
            call reserve(recvbuf, border_width*sw%nrecv, minimum=1024)
            do j = 1, ns
                i = sw%list(j); p = border_width*(j - 1)
                sendbuf(p + 1:p + 3) = atoms%x(:, i) + sw%shift
                sendbuf(p + 4:p + 6) = atoms%v(:, i)
                sendbuf(p + 7) = real(atoms%type(i), dp)
                sendbuf(p + 8) = real(atoms%id(i), dp)
            end do
            call MPI_Sendrecv(sendbuf, border_width*ns, MPI_DOUBLE_PRECISION, sw%send_to, 11, &
                              recvbuf, border_width*sw%nrecv, MPI_DOUBLE_PRECISION, &
                              sw%recv_from, 11, cart, MPI_STATUS_IGNORE)
            do j = 1, sw%nrecv
                n = sw%first_recv + j - 1; p = border_width*(j - 1)
                atoms%x(:, n) = recvbuf(p + 1:p + 3)
                atoms%v(:, n) = recvbuf(p + 4:p + 6)
                atoms%type(n) = nint(recvbuf(p + 7))
                atoms%id(n) = nint(recvbuf(p + 8), i8)
            end do
        end if
        atoms%nghost = atoms%nghost + sw%nrecv
    end subroutine exchange_borders

    !> Forward communication: copy owner values of a per-atom quantity with nc components
    !> (a(nc, n): positions with the periodic shift when `shifted`, velocities, F'(rho), ...) into
    !> the ghosts. The two directions of one hop along a divided dimension travel together.
    subroutine domain_forward(self, a, shifted)
        class(domain_t), intent(inout) :: self
        real(dp), intent(inout), contiguous :: a(:, :)
        logical, intent(in) :: shifted
        integer :: s, g, k, j, i, n, p, nc
        real(dp) :: sh(size(a, 1))
        nc = size(a, 1)
        s = 1
        do while (s <= self%nswap)
            g = group_size(self, s)
            if (self%swaps(s)%self_copy) then
                associate (sw => self%swaps(s))
                    sh = 0
                    if (shifted) sh = sw%shift(1:nc)
                    if (nc == 3) then
                        ! (three components spelt out: the loop over an unknown nc was the copy's cost)
                        do j = 1, sw%nsend
                            i = sw%list(j); n = sw%first_recv + j - 1
                            a(1, n) = a(1, i) + sh(1); a(2, n) = a(2, i) + sh(2); a(3, n) = a(3, i) + sh(3)
                        end do
                    else
                        do j = 1, sw%nsend
                            a(:, sw%first_recv + j - 1) = a(:, sw%list(j)) + sh
                        end do
                    end if
                end associate
            else
                call reserve_group(self, s, g, nc, .true.)
                p = 0
                do k = s, s + g - 1
                    associate (sw => self%swaps(k))
                        sh = 0
                        if (shifted) sh = sw%shift(1:nc)
                        do j = 1, sw%nsend
                            i = sw%list(j)
                            self%sendbuf(p + 1:p + nc) = a(:, i) + sh
                            p = p + nc
                        end do
                    end associate
                end do
                call exchange_group(self, s, g, nc, .true., 12)
                p = 0
                do k = s, s + g - 1
                    associate (sw => self%swaps(k))
                        do j = 1, sw%nrecv
                            n = sw%first_recv + j - 1
                            a(:, n) = self%recvbuf(p + 1:p + nc)
                            p = p + nc
                        end do
                    end associate
                end do
            end if
            s = s + g
        end do
    end subroutine domain_forward

    !> Forward communication of positions (shifted across periodic faces) and velocities together:
    !> one pass over each swap's atoms and one message per swap, where domain_forward would make two
    !> (energy stepping's ghosts after each velocity jump).
    subroutine domain_forward_xv(self, x, v)
        class(domain_t), intent(inout) :: self
        real(dp), intent(inout), contiguous :: x(:, :), v(:, :)
        integer :: s, g, k, j, i, n, p
        real(dp) :: sx, sy, sz
        s = 1
        do while (s <= self%nswap)
            g = group_size(self, s)
            if (self%swaps(s)%self_copy) then
                associate (sw => self%swaps(s))
                    sx = sw%shift(1); sy = sw%shift(2); sz = sw%shift(3)
                    do j = 1, sw%nsend
                        i = sw%list(j); n = sw%first_recv + j - 1
                        x(1, n) = x(1, i) + sx; x(2, n) = x(2, i) + sy; x(3, n) = x(3, i) + sz
                        v(1, n) = v(1, i); v(2, n) = v(2, i); v(3, n) = v(3, i)
                    end do
                end associate
            else
                call reserve_group(self, s, g, 6, .true.)
                p = 0
                do k = s, s + g - 1
                    associate (sw => self%swaps(k))
                        sx = sw%shift(1); sy = sw%shift(2); sz = sw%shift(3)
                        do j = 1, sw%nsend
                            i = sw%list(j)
                            self%sendbuf(p + 1) = x(1, i) + sx; self%sendbuf(p + 2) = x(2, i) + sy
                            self%sendbuf(p + 3) = x(3, i) + sz
                            self%sendbuf(p + 4:p + 6) = v(:, i)
                            p = p + 6
                        end do
                    end associate
                end do
                call exchange_group(self, s, g, 6, .true., 14)
                p = 0
                do k = s, s + g - 1
                    associate (sw => self%swaps(k))
                        do j = 1, sw%nrecv
                            n = sw%first_recv + j - 1
                            x(:, n) = self%recvbuf(p + 1:p + 3); v(:, n) = self%recvbuf(p + 4:p + 6)
                            p = p + 6
                        end do
                    end associate
                end do
            end if
            s = s + g
        end do
    end subroutine domain_forward_xv

    !> Reverse communication: add ghost values of a per-atom quantity with nc components (forces,
    !> densities) back into their owners, swap by swap in reverse order (so ghosts of ghosts pass
    !> their share on). The two directions of one hop travel together; their sums are added in the
    !> same order as one swap after the other would add them.
    subroutine domain_reverse(self, a)
        class(domain_t), intent(inout) :: self
        real(dp), intent(inout), contiguous :: a(:, :)
        integer :: s, g, k, j, i, n, p, nc, first
        nc = size(a, 1)
        s = self%nswap
        do while (s >= 1)
            g = 1
            if (s >= 2) then
                if (self%swaps(s - 1)%with_next) g = 2
            end if
            first = s - g + 1
            if (self%swaps(s)%self_copy) then
                associate (sw => self%swaps(s))
                    if (nc == 3) then
                        do j = 1, sw%nsend
                            i = sw%list(j); n = sw%first_recv + j - 1
                            a(1, i) = a(1, i) + a(1, n); a(2, i) = a(2, i) + a(2, n); a(3, i) = a(3, i) + a(3, n)
                        end do
                    else
                        do j = 1, sw%nsend
                            i = sw%list(j)
                            a(:, i) = a(:, i) + a(:, sw%first_recv + j - 1)
                        end do
                    end if
                end associate
            else
                call reserve_group(self, first, g, nc, .false.)
                p = 0
                do k = first, s
                    associate (sw => self%swaps(k))
                        do j = 1, sw%nrecv
                            n = sw%first_recv + j - 1
                            self%sendbuf(p + 1:p + nc) = a(:, n)
                            p = p + nc
                        end do
                    end associate
                end do
                call exchange_group(self, first, g, nc, .false., 13)
                ! the later swap's sums first, as the swaps one by one in reverse order
                do k = s, first, -1
                    p = 0
                    if (k > first) p = nc*self%swaps(first)%nsend
                    associate (sw => self%swaps(k))
                        do j = 1, sw%nsend
                            i = sw%list(j)
                            a(:, i) = a(:, i) + self%recvbuf(p + 1:p + nc)
                            p = p + nc
                        end do
                    end associate
                end do
            end if
            s = first - 1
        end do
    end subroutine domain_reverse

    !> How many swaps from s on travel together: 2 where s and s + 1 are the two directions of one
    !> hop along a divided dimension (independent: each sends from atoms the other does not
    !> receive), else 1.
    pure integer function group_size(self, s) result(g)
        class(domain_t), intent(in) :: self
        integer, intent(in) :: s
        g = 1
        if (self%swaps(s)%with_next .and. s < self%nswap) g = 2
    end function group_size

    !> Room in sendbuf and recvbuf for the g swaps from s on, nc values per atom: forward sends the
    !> swaps' lists and receives their ghosts, reverse the other way.
    subroutine reserve_group(self, s, g, nc, forward)
        class(domain_t), intent(inout) :: self
        integer, intent(in) :: s, g, nc
        logical, intent(in) :: forward
        integer :: ns, nr, k
        ns = 0; nr = 0
        do k = s, s + g - 1
            ns = ns + self%swaps(k)%nsend; nr = nr + self%swaps(k)%nrecv
        end do
        if (.not. forward) then
            k = ns; ns = nr; nr = k
        end if
        call reserve(self%sendbuf, nc*ns, minimum=1024)
        call reserve(self%recvbuf, nc*nr, minimum=1024)
    end subroutine reserve_group

    !> The messages of the g swaps from s on, all posted at once: sendbuf and recvbuf hold the swaps'
    !> values one after the other, nc per atom. Forward: each swap sends its list to send_to and
    !> receives its ghosts from recv_from; reverse: its ghosts back to recv_from, its list's sums from
    !> send_to. The tag tells the two directions apart where both neighbours are one rank.
    subroutine exchange_group(self, s, g, nc, forward, tag)
        class(domain_t), intent(inout) :: self
        integer, intent(in) :: s, g, nc, tag
        logical, intent(in) :: forward
        type(MPI_Request) :: req(4)
        integer :: k, ps, pr, ns, nr, to, from
        ps = 1; pr = 1
        do k = 0, g - 1
            associate (sw => self%swaps(s + k))
                if (forward) then
                    ns = sw%nsend; nr = sw%nrecv; to = sw%send_to; from = sw%recv_from
                else
                    ns = sw%nrecv; nr = sw%nsend; to = sw%recv_from; from = sw%send_to
                end if
                call MPI_Irecv(self%recvbuf(pr:), nc*nr, MPI_DOUBLE_PRECISION, from, tag + 100*sw%dir, &
                               self%cart, req(2*k + 1))
                call MPI_Isend(self%sendbuf(ps:), nc*ns, MPI_DOUBLE_PRECISION, to, tag + 100*sw%dir, &
                               self%cart, req(2*k + 2))
                ps = ps + nc*ns; pr = pr + nc*nr
            end associate
        end do
        call MPI_Waitall(2*g, req, MPI_STATUSES_IGNORE)
        call MPI_F_sync_reg(self%recvbuf)
    end subroutine exchange_group

end module terrace_domain
