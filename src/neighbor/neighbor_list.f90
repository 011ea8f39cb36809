!> Cell (bin) lists feeding a half Verlet neighbour list with skin.
!>
!> Bins are about (rc + skin)/2 wide and cover this rank's atoms plus the ghost shell. Owned
!> atoms are sorted by bin at every rebuild (spatial locality, and it makes the half-list rule
!> cheap): owned j is a neighbour of owned i iff j > i, which, with atoms sorted by bin, means j in
!> the same bin after i or in a bin of the "upper" half stencil. A ghost j is a neighbour of i iff
!> it is "above" i in (z, y, x) order: the rank that owns j sees i as a ghost "below" it and skips
!> the pair, so each pair is counted exactly once across ranks and periodic images.
!> The list is valid until some atom has moved skin/2 since the build.
module terrace_neighbor_list
    use terrace_kinds, only: dp
    use terrace_atoms, only: atoms_t
    use terrace_mpi_env, only: any_all
    implicit none
    private

    type, public :: neighbor_list_t
        real(dp) :: cut = 0, cutsq = 0, skin = 0
        integer :: dimension = 3
        integer :: nbin(3) = 1, reach(3) = 0
        real(dp) :: bin_lo(3) = 0, bin_inv(3) = 1, bin_size(3) = 1
        integer, allocatable :: atom_bin(:)
        integer, allocatable :: owned_start(:)
        integer, allocatable :: ghost_start(:), ghost_atoms(:)
        integer, allocatable :: row_lo(:), row_hi(:)   !< stencil rows (x-runs of bins): linear offsets
        integer :: nrows = 0, first_upper_row = 1       !< rows first_upper_row.. are the upper half
        integer :: center_reach = 0                     !< x-reach of the centre row
        integer :: stencil_bins = 0
        integer, allocatable :: first(:), neigh(:)
        real(dp), allocatable :: xhold(:, :)
        integer, allocatable :: perm(:), counts(:)
        integer :: builds = 0
        integer :: max_neighbors = 0                    !< longest row of the list
    contains
        procedure :: init => nl_init
        procedure :: setup_bins => nl_setup_bins
        procedure :: sort_owned => nl_sort_owned
        procedure :: build => nl_build
        procedure :: needs_rebuild => nl_needs_rebuild
    end type neighbor_list_t

contains

    subroutine nl_init(self, cut, skin, dimension)
        class(neighbor_list_t), intent(inout) :: self
        real(dp), intent(in) :: cut, skin
        integer, intent(in) :: dimension
        self%cut = cut + skin
        self%cutsq = self%cut**2
        self%skin = skin
        self%dimension = dimension
    end subroutine nl_init

    !> Lay out bins over [lo, hi] (this rank's region of interest: owned atoms, its brick and the
    !> ghost shell), padded by the stencil reach so that no stencil offset leaves the grid.
    subroutine nl_setup_bins(self, lo, hi, natoms_hint)
        class(neighbor_list_t), intent(inout) :: self
        real(dp), intent(in) :: lo(3), hi(3)
        integer, intent(in) :: natoms_hint
        integer :: d, nb(3), ntot, sx, sy, sz, n, maxbins, pass, sxmax, base
        real(dp) :: ext(3), target, dist2
        target = 0.5_dp*self%cut
        ext = max(hi - lo, target)
        maxbins = max(8*natoms_hint, 4096)
        do
            nb = 1
            do d = 1, self%dimension
                nb(d) = max(1, int(ext(d)/target))
            end do
            if (product(real(nb, dp)) <= maxbins) exit
            target = target*1.26_dp
        end do
        self%bin_size = ext/nb
        self%bin_inv = 1.0_dp/self%bin_size
        self%reach = 0
        do d = 1, self%dimension
            self%reach(d) = ceiling(self%cut*self%bin_inv(d))
        end do
        self%nbin = nb + 2*self%reach
        self%bin_lo = lo - self%reach*self%bin_size
        ntot = product(self%nbin)
        if (allocated(self%owned_start)) then
            if (size(self%owned_start) < ntot + 1) deallocate (self%owned_start, self%ghost_start)
        end if
        if (.not. allocated(self%owned_start)) allocate (self%owned_start(ntot + 1), self%ghost_start(ntot + 1))
        ! stencil as rows of bins along x: lower rows, then upper rows (centre row kept apart)
        if (allocated(self%row_lo)) deallocate (self%row_lo, self%row_hi)
        allocate (self%row_lo((2*self%reach(2) + 1)*(2*self%reach(3) + 1)), &
                  self%row_hi((2*self%reach(2) + 1)*(2*self%reach(3) + 1)))
        n = 0
        self%stencil_bins = 0
        do pass = 1, 2
            if (pass == 2) self%first_upper_row = n + 1
            do sz = -self%reach(3), self%reach(3)
                do sy = -self%reach(2), self%reach(2)
                    if (sz == 0 .and. sy == 0) cycle
                    if ((pass == 2) .neqv. (sz > 0 .or. (sz == 0 .and. sy > 0))) cycle
                    sxmax = -1
                    do sx = 0, self%reach(1)
                        dist2 = (max(0, sx - 1)*self%bin_size(1))**2 + (max(0, abs(sy) - 1)*self%bin_size(2))**2 + &
                                (max(0, abs(sz) - 1)*self%bin_size(3))**2
                        if (dist2 < self%cutsq) sxmax = sx
                    end do
                    if (sxmax < 0) cycle
                    n = n + 1
                    base = self%nbin(1)*(sy + self%nbin(2)*sz)
                    self%row_lo(n) = base - sxmax
                    self%row_hi(n) = base + sxmax
                    self%stencil_bins = self%stencil_bins + 2*sxmax + 1
                end do
            end do
        end do
        self%nrows = n
        self%center_reach = self%reach(1)
        self%stencil_bins = self%stencil_bins + 2*self%reach(1) + 1
    end subroutine nl_setup_bins

    pure integer function bin_of(self, x) result(b)
        class(neighbor_list_t), intent(in) :: self
        real(dp), intent(in) :: x(3)
        integer :: c(3), d
        do d = 1, 3
            c(d) = int(floor((x(d) - self%bin_lo(d))*self%bin_inv(d)))
            c(d) = min(self%nbin(d) - 1 - self%reach(d), max(self%reach(d), c(d)))
        end do
        b = 1 + c(1) + self%nbin(1)*(c(2) + self%nbin(2)*c(3))
    end function bin_of

    !> Counting sort of the owned atoms by bin; fills owned_start.
    subroutine nl_sort_owned(self, atoms)
        class(neighbor_list_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        integer :: i, b, ntot, n
        n = atoms%nlocal
        ntot = product(self%nbin)
        call ensure_int(self%atom_bin, max(n, 1))
        call ensure_int(self%perm, max(n, 1))
        call ensure_int(self%counts, ntot + 1)
        self%counts(1:ntot + 1) = 0
        do i = 1, n
            b = bin_of(self, atoms%x(:, i))
            self%atom_bin(i) = b
            self%counts(b + 1) = self%counts(b + 1) + 1
        end do
        self%counts(1) = 1
        do b = 2, ntot + 1
            self%counts(b) = self%counts(b) + self%counts(b - 1)
        end do
        self%owned_start(1:ntot + 1) = self%counts(1:ntot + 1)
        do i = 1, n
            b = self%atom_bin(i)
            self%perm(self%counts(b)) = i
            self%counts(b) = self%counts(b) + 1
        end do
        call atoms%permute_owned(self%perm(1:n))
    end subroutine nl_sort_owned

    !> Build the half list (owned atoms sorted, ghosts present). Remembers positions for the
    !> skin/2 displacement test.
    subroutine nl_build(self, atoms)
        class(neighbor_list_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        integer :: i, b, n, ntot, nall, nlocal, maxbin, bound
        real(dp) :: cutsq
        nlocal = atoms%nlocal
        nall = atoms%nlocal + atoms%nghost
        ntot = product(self%nbin)
        cutsq = self%cutsq
        ! ghosts by bin
        call ensure_int(self%atom_bin, max(nall, 1))
        call ensure_int(self%ghost_atoms, max(atoms%nghost, 1))
        call ensure_int(self%counts, ntot + 1)
        self%counts(1:ntot + 1) = 0
        do i = 1, nlocal
            self%atom_bin(i) = bin_of(self, atoms%x(:, i))
        end do
        do i = nlocal + 1, nall
            b = bin_of(self, atoms%x(:, i))
            self%atom_bin(i) = b
            self%counts(b + 1) = self%counts(b + 1) + 1
        end do
        self%counts(1) = 1
        do b = 2, ntot + 1
            self%counts(b) = self%counts(b) + self%counts(b - 1)
        end do
        self%ghost_start(1:ntot + 1) = self%counts(1:ntot + 1)
        do i = nlocal + 1, nall
            b = self%atom_bin(i)
            self%ghost_atoms(self%counts(b)) = i
            self%counts(b) = self%counts(b) + 1
        end do
        maxbin = 0
        do b = 1, ntot
            maxbin = max(maxbin, self%owned_start(b + 1) - self%owned_start(b) + self%ghost_start(b + 1) - &
                         self%ghost_start(b))
        end do
        bound = maxbin*self%stencil_bins
        call ensure_int(self%first, nlocal + 1)
        call ensure_int(self%neigh, max(nlocal*32, bound, 1024))
        n = 0
        do i = 1, nlocal
            if (n + bound > size(self%neigh)) call grow_int(self%neigh, n, n + bound)
            call half_list_of_atom(i, atoms%x, self%atom_bin(i), self%owned_start, self%ghost_start, self%ghost_atoms, &
                                   self%row_lo, self%row_hi, self%first_upper_row, self%nrows, self%center_reach, &
                                   cutsq, self%neigh, n)
            self%first(i + 1) = n + 1
        end do
        self%first(1) = 1
        self%max_neighbors = 0
        do i = 1, nlocal
            self%max_neighbors = max(self%max_neighbors, self%first(i + 1) - self%first(i))
        end do
        if (allocated(self%xhold)) then
            if (size(self%xhold, 2) < nlocal) deallocate (self%xhold)
        end if
        if (.not. allocated(self%xhold)) allocate (self%xhold(3, max(nlocal, 1) + nlocal/4))
        self%xhold(:, 1:nlocal) = atoms%x(:, 1:nlocal)
        self%builds = self%builds + 1
    end subroutine nl_build

    !> Neighbours of owned atom i appended to neigh(n+1:): owned j > i (same bin after i, the rest
    !> of the centre row, the upper rows: contiguous index ranges since owned atoms are sorted by
    !> bin) and ghosts above i in (z, y, x) order from every row. The append is branch-free.
    subroutine half_list_of_atom(i, x, b, owned_start, ghost_start, ghost_atoms, row_lo, row_hi, first_upper, nrows, &
                                 center_reach, cutsq, neigh, n)
        integer, intent(in) :: i, b, first_upper, nrows, center_reach
        real(dp), intent(in), contiguous :: x(:, :)
        integer, intent(in), contiguous :: owned_start(:), ghost_start(:), ghost_atoms(:), row_lo(:), row_hi(:)
        real(dp), intent(in) :: cutsq
        integer, intent(inout), contiguous :: neigh(:)
        integer, intent(inout) :: n
        integer :: j, k, r
        real(dp) :: xi, yi, zi, dx, dy, dz, rsq
        xi = x(1, i); yi = x(2, i); zi = x(3, i)
        do j = i + 1, owned_start(b + center_reach + 1) - 1
            dx = xi - x(1, j); dy = yi - x(2, j); dz = zi - x(3, j)
            rsq = dx*dx + dy*dy + dz*dz
            neigh(n + 1) = j
            if (rsq < cutsq) n = n + 1
        end do
        do r = first_upper, nrows
            do j = owned_start(b + row_lo(r)), owned_start(b + row_hi(r) + 1) - 1
                dx = xi - x(1, j); dy = yi - x(2, j); dz = zi - x(3, j)
                rsq = dx*dx + dy*dy + dz*dz
                neigh(n + 1) = j
                if (rsq < cutsq) n = n + 1
            end do
        end do
        do r = 0, nrows
            if (r == 0) then
                k = ghost_start(b - center_reach)
                j = ghost_start(b + center_reach + 1) - 1
            else
                k = ghost_start(b + row_lo(r))
                j = ghost_start(b + row_hi(r) + 1) - 1
            end if
            call ghosts_above(k, j)
        end do
    contains
        subroutine ghosts_above(kfirst, klast)
            integer, intent(in) :: kfirst, klast
            integer :: kk, jj
            do kk = kfirst, klast
                jj = ghost_atoms(kk)
                dz = x(3, jj) - zi
                if (dz < 0) cycle
                dy = x(2, jj) - yi
                dx = x(1, jj) - xi
                if (dz == 0) then
                    if (dy < 0) cycle
                    if (dy == 0 .and. dx <= 0) cycle
                end if
                rsq = dx*dx + dy*dy + dz*dz
                neigh(n + 1) = jj
                if (rsq < cutsq) n = n + 1
            end do
        end subroutine ghosts_above
    end subroutine half_list_of_atom

    !> True on every rank if any owned atom anywhere moved more than skin/2 since the build.
    logical function nl_needs_rebuild(self, atoms) result(flag)
        class(neighbor_list_t), intent(in) :: self
        type(atoms_t), intent(in) :: atoms
        integer :: i
        real(dp) :: limit, dx, dy, dz
        limit = (0.5_dp*self%skin)**2
        flag = .false.
        do i = 1, atoms%nlocal
            dx = atoms%x(1, i) - self%xhold(1, i)
            dy = atoms%x(2, i) - self%xhold(2, i)
            dz = atoms%x(3, i) - self%xhold(3, i)
            if (dx*dx + dy*dy + dz*dz > limit) then
                flag = .true.
                exit
            end if
        end do
        call any_all(flag)
    end function nl_needs_rebuild

    subroutine ensure_int(a, n)
        integer, allocatable, intent(inout) :: a(:)
        integer, intent(in) :: n
        if (allocated(a)) then
            if (size(a) >= n) return
            deallocate (a)
        end if
        allocate (a(n + n/4))
    end subroutine ensure_int

    subroutine grow_int(a, keep, n)
        integer, allocatable, intent(inout) :: a(:)
        integer, intent(in) :: keep, n
        integer, allocatable :: t(:)
        allocate (t(max(n, 2*size(a))))
        t(1:keep) = a(1:keep)
        call move_alloc(t, a)
    end subroutine grow_int

end module terrace_neighbor_list
