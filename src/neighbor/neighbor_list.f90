!> Cell (bin) lists feeding a half Verlet neighbour list with skin.
!>
!> Bins are at least rc + skin wide along x (and y in 3-D) and about (rc + skin)/2 along the last
!> dimension (see nl_setup_bins), and cover this rank's atoms plus the ghost shell. Owned
!> atoms are sorted by bin at every rebuild (spatial locality, and it makes the half-list rule
!> cheap): owned j is a neighbour of owned i iff j > i, which, with atoms sorted by bin, means j in
!> the same bin after i or in a bin of the "upper" half stencil. A ghost j is a neighbour of i iff
!> it is "above" i in (z, y, x) order: the rank that owns j sees i as a ghost "below" it and skips
!> the pair, so each pair is counted exactly once across ranks and periodic images.
!> The list is valid until some atom has moved skin/2 since the build.
module terrace_neighbor_list
    use, intrinsic :: iso_c_binding, only: c_int, c_double
    use terrace_kinds, only: dp, i8
    use terrace_atoms, only: atoms_t
    use terrace_mpi_env, only: any_all
    use terrace_grow, only: reserve, grow_keep
    use terrace_cluster_list, only: cluster_list_t
    implicit none
    private
    public :: gather_neighbour_types, order_rows_by_type, longest_row, row_offsets

    type, public :: neighbor_list_t
        real(dp) :: cut = 0, cutsq = 0, skin = 0
        !> No list: every owned atom meets every atom this rank holds (small free scenes; the
        !> scene plan decides). Potentials that support it branch on this once per pass.
        logical :: all_pairs = .false.
        integer :: dimension = 3
        integer :: nbin(3) = 1, reach(3) = 0
        real(dp) :: bin_lo(3) = 0, bin_inv(3) = 1, bin_size(3) = 1
        integer, allocatable :: atom_bin(:)
        integer, allocatable :: owned_start(:)
        integer, allocatable :: ghost_start(:), ghost_atoms(:)
        integer, allocatable :: row_lo(:), row_hi(:)   !< stencil rows (x-runs of bins): linear offsets
        integer, allocatable :: row_dz(:)               !< z offset (in bins) of each stencil row
        integer :: nrows = 0, first_upper_row = 1       !< rows first_upper_row.. are the upper half
        integer :: center_reach = 0                     !< x-reach of the centre row
        integer :: stencil_bins = 0
        integer, allocatable :: first(:), neigh(:)
        real(dp), allocatable :: xhold(:, :)
        !> The box's scale since the last build (per dimension; a barostat's rescalings that kept the
        !> list): xhold is scaled with the positions, and the skin left is min(1, scaled) (rc + skin) - rc.
        real(dp) :: scaled(3) = 1
        integer, allocatable :: perm(:), counts(:)
        real(dp), allocatable :: cx(:), cy(:), cz(:)    !< build scratch: candidates shared by a bin's atoms
        integer, allocatable :: cj(:), keep(:)
        !> Build scratch: the positions in bin order, columns of contiguous rows (owned slot k is atom
        !> k, sorted by bin; ghost slot nlocal + s is atom ghost_atoms(s)), so that the candidates of a
        !> stencil row are copied as contiguous blocks; sj(slot) is the atom.
        real(dp), allocatable :: sx(:), sy(:), sz(:)
        integer, allocatable :: sj(:)
        integer :: builds = 0
        !> Rebuild schedule (&neighbor every, check): exact (every = 1, check) tests the skin/2
        !> displacement at every step; otherwise the list is checked (or, without check, rebuilt)
        !> every `every` steps only, and `late` counts the builds at which some atom had already moved
        !> more than skin/2 (the list was no longer sure to hold every pair within the cutoff).
        integer :: every = 1
        logical :: check = .true.
        integer :: late = 0
        integer :: max_neighbors = 0                    !< longest row of the list
        !> Optional complement (want_below): for each owned atom i, the ghosts within the list
        !> cutoff that the half list leaves to their owners (those "below" i in (z, y, x) order);
        !> with the half list, each owned atom's full neighbourhood (EAM densities without a
        !> reverse sum). below(below_first(i) : below_first(i+1)-1).
        logical :: want_below = .false.
        !> Set before each build (terrace_domain's half_images, the halo it built): every ghost is a
        !> periodic image of an owned atom under a "positive" shift, and each pair of an owned atom
        !> with a ghost is this rank's: every ghost within the cutoff is a neighbour, found over the
        !> whole stencil (no (z, y, x) test). Not with want_below or want_clusters.
        logical :: half_images = .false.
        integer, allocatable :: below_first(:), below(:)
        integer :: max_below = 0
        !> Optional (want_types): the type of each neighbour, ntype(k) = type(neigh(k)), filled at each
        !> build (and carried by a pruned copy), so that multi-type pair passes read the types as a
        !> contiguous row instead of gathering them at every step. Eight entries past the last row
        !> are valid types too (the pad of eight-lane loops).
        logical :: want_types = .false.
        integer, allocatable :: ntype(:)
        !> Optional (type_order = the number of types, > 1): each row ordered by the neighbours'
        !> types (the scan's order kept within a type), the type-b neighbours of owned atom i at
        !> neigh(tfirst(g) : tfirst(g+1)-1), g = (i-1)*type_order + b, set at each build and carried
        !> by a pruned copy; so that multi-type passes pick a pair's tables once per segment instead
        !> of per neighbour (EAM). 0: rows in scan order, tfirst unset.
        integer :: type_order = 0
        integer, allocatable :: tfirst(:), tscratch(:, :)
        !> Optional (want_clusters, 3-D): a cluster-pair list (terrace_cluster_list) at the list
        !> cutoff in place of the atom rows, for a kernel over clusters (the mixed-precision LJ
        !> kernel). The first build also builds the atom rows (the start-up overlap check reads
        !> them); later builds leave every row empty (first(:) = 1), so that nothing reads stale rows.
        logical :: want_clusters = .false.
        type(cluster_list_t) :: clusters
        !> Wrapped images (set by the engine, terrace_engine's wrap_images): every ghost this rank holds
        !> is a periodic image of one of its owned atoms, image_of(j) the owner of atom j held (j
        !> itself when owned; a built list's only: a pruned one takes its offsets from it), and the box, wrap_box = (lo, length), is more than twice the list's
        !> cutoff in every dimension, so that each pair of the list is its two atoms at their nearest
        !> images. A pass that can (potential%wraps_images) then reads each ghost as its owner there,
        !> and leaves the ghosts' positions unread and their forces untouched.
        logical :: wrapped = .false.
        integer, allocatable :: image_of(:)
        real(dp) :: wrap_box(6) = 0
        !> With wrapped images: the rows as byte offsets of the owners' fixed-point records (row i at
        !> offs(ofirst(i) + 1 : ofirst(i + 1)), padded to 16 entries; row_offsets), formed at the build
        !> count offs_build (wrap_offsets for a built list, the fixed-point prune for a pruned one);
        !> q: the prune's fixed-point positions (core/fixed_point_rows.h)
        integer, allocatable :: ofirst(:), offs(:), q(:)
        integer :: offs_build = -1
    contains
        procedure :: init => nl_init
        procedure :: setup_bins => nl_setup_bins
        procedure :: sort_owned => nl_sort_owned
        procedure :: build => nl_build
        procedure :: hold => nl_hold
        procedure :: needs_rebuild => nl_needs_rebuild
        procedure :: scale_reference => nl_scale_reference
        procedure :: rebuild_due => nl_rebuild_due
        procedure :: prune => nl_prune
        procedure :: exact => nl_exact
        procedure :: expiry => nl_expiry
        procedure :: moved_beyond => nl_moved_beyond
        procedure :: wrap_offsets => nl_wrap_offsets
        procedure :: prune_reads_ghosts => nl_prune_reads_ghosts
    end type neighbor_list_t

    interface
        !> src/neighbor/scan_simd.c: scan with AVX-512 or AVX2 (-1: neither in this build)
        integer(c_int) function c_scan_compress(xi, yi, zi, cx, cy, cz, cj, k1, k2, cutsq, above, out) &
            bind(C, name='terrace_scan_compress')
            import :: c_int, c_double
            real(c_double), value :: xi, yi, zi, cutsq
            real(c_double), intent(in) :: cx(*), cy(*), cz(*)
            integer(c_int), intent(in) :: cj(*)
            integer(c_int), value :: k1, k2, above
            integer(c_int), intent(inout) :: out(*)
        end function c_scan_compress
        !> src/neighbor/prune_simd.c: keep_within with AVX-512 or AVX2 (-1: neither in this build)
        integer(c_int) function c_prune_compress(xi, yi, zi, x, nb, k1, k2, cutsq, out) &
            bind(C, name='terrace_prune_compress')
            import :: c_int, c_double
            real(c_double), value :: xi, yi, zi, cutsq
            real(c_double), intent(in) :: x(*)
            integer(c_int), intent(in) :: nb(*)
            integer(c_int), value :: k1, k2
            integer(c_int), intent(inout) :: out(*)
        end function c_prune_compress
        !> src/neighbor/prune_simd.c: the rows as byte offsets of fixed-point records (-1: not in this build)
        integer(c_int) function c_row_offsets(nlocal, nrec, first, neigh, wrapped, origin, ofirst, offs) &
            bind(C, name='terrace_row_offsets')
            import :: c_int
            integer(c_int), value :: nlocal, nrec, wrapped
            integer(c_int), intent(in) :: first(*), neigh(*), origin(*)
            integer(c_int), intent(inout) :: ofirst(*), offs(*)
        end function c_row_offsets
        !> src/neighbor/prune_simd.c: the fixed-point prune of a list with wrapped images (-1: not in this build)
        integer(c_int) function c_prune_wrapped(nlocal, x, wrap, q, first, neigh, ofirst, offs, cutsq, first_in, &
                                                neigh_in, ofirst_in, offs_in) bind(C, name='terrace_prune_wrapped')
            import :: c_int, c_double
            integer(c_int), value :: nlocal
            real(c_double), intent(in) :: x(*), wrap(6)
            real(c_double), value :: cutsq
            integer(c_int), intent(inout) :: q(*), first_in(*), neigh_in(*), ofirst_in(*), offs_in(*)
            integer(c_int), intent(in) :: first(*), neigh(*), ofirst(*), offs(*)
        end function c_prune_wrapped
    end interface

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
        real(dp) :: ext(3), target, dist2, width(3)
        target = 0.5_dp*self%cut
        ext = max(hi - lo, target)
        maxbins = max(8*natoms_hint, 4096)
        ! bins at least rc + skin wide across the stencil's rows (x, and y in 3-D: reach 1, rows of
        ! three bins) and half that along the last dimension (reach 2): fewer, fuller bins than half
        ! the cutoff everywhere, so that a bin's shared candidates serve about 9 atoms instead of 2.6
        ! (scripts/bench/phase_ab.sh, 7 rounds: the build about 13 % cheaper on the LJ benchmark scene,
        ! 28 % on Cu EAM; doc/performance.md)
        ! The bins are as wide as that and no wider (a hair more, so that the stencil's reach is the
        ! rounded-up ratio without round-off): the grid covers at least [lo, hi], its last bin
        ! sticking out; bins stretched to tile [lo, hi] exactly would scan more candidates on small
        ! boxes, up to (1 + 1/nb)^3 (doc/performance.md, list builds per atom)
        do
            nb = 1
            width = target
            do d = 1, self%dimension
                width(d) = target*merge(2.0_dp, 1.0_dp, d < self%dimension)*(1.0_dp + 1.0e-12_dp)
                nb(d) = max(1, ceiling(ext(d)/width(d)))
            end do
            if (product(real(nb, dp)) <= maxbins) exit
            target = target*1.26_dp
        end do
        do d = 1, 3
            self%bin_size(d) = merge(width(d), ext(d)/nb(d), d <= self%dimension)
        end do
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
        if (allocated(self%row_lo)) deallocate (self%row_lo, self%row_hi, self%row_dz)
        allocate (self%row_lo((2*self%reach(2) + 1)*(2*self%reach(3) + 1)), &
                  self%row_hi((2*self%reach(2) + 1)*(2*self%reach(3) + 1)), &
                  self%row_dz((2*self%reach(2) + 1)*(2*self%reach(3) + 1)))
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
                    self%row_dz(n) = sz
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
        ! (truncation, not floor: the two differ below zero only, which the clamp maps to reach >= 0
        ! either way; it saves the rounding on every atom binned)
        do d = 1, 3
            c(d) = int((x(d) - self%bin_lo(d))*self%bin_inv(d))
            c(d) = min(self%nbin(d) - 1 - self%reach(d), max(self%reach(d), c(d)))
        end do
        b = 1 + c(1) + self%nbin(1)*(c(2) + self%nbin(2)*c(3))
    end function bin_of

    !> Counting sort of the owned atoms by bin; fills owned_start.
    subroutine nl_sort_owned(self, atoms)
        class(neighbor_list_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        integer :: n
        n = atoms%nlocal
        call reserve(self%atom_bin, max(n, 1))
        call reserve(self%perm, max(n, 1))
        call bin_sort(self, atoms%x, 1, n, self%owned_start, self%perm)
        call atoms%permute_owned(self%perm(1:n))
    end subroutine nl_sort_owned

    !> Counting sort of atoms i1..i2 by bin (atom_bin(i1:i2) set): start(b) is the first slot of
    !> bin b (start(ntot + 1) one past the last) and order(start(b) : start(b + 1) - 1) its atoms in
    !> index order.
    subroutine bin_sort(self, x, i1, i2, start, order)
        type(neighbor_list_t), intent(inout) :: self
        real(dp), intent(in) :: x(:, :)
        integer, intent(in) :: i1, i2
        integer, intent(inout) :: start(:), order(:)
        integer :: i, b, ntot
        ntot = product(self%nbin)
        call reserve(self%counts, ntot + 1)
        self%counts(1:ntot + 1) = 0
        do i = i1, i2
            b = bin_of(self, x(:, i))
            self%atom_bin(i) = b
            self%counts(b + 1) = self%counts(b + 1) + 1
        end do
        self%counts(1) = 1
        do b = 2, ntot + 1
            self%counts(b) = self%counts(b) + self%counts(b - 1)
        end do
        start(1:ntot + 1) = self%counts(1:ntot + 1)
        do i = i1, i2
            b = self%atom_bin(i)
            order(self%counts(b)) = i
            self%counts(b) = self%counts(b) + 1
        end do
    end subroutine bin_sort

    !> Build the half list (owned atoms sorted, ghosts present). Remembers positions for the
    !> skin/2 displacement test.
    !>
    !> Bin by bin: the candidates that all atoms of bin b share (owned atoms in the rest of the
    !> centre row and in the upper rows; ghosts in the rows above in z, which are all above every
    !> atom of b in (z, y, x) order since bins are monotone in z) are copied once into contiguous
    !> scratch rows (block copies from the positions in bin order, bin_order_columns: a stencil row
    !> of bins is one contiguous run of slots), then each atom of b scans them with a vectorised
    !> distance pass and a scalar branch-free compaction. Per atom remain the owned atoms after it in its own bin and the ghosts
    !> of the rows at the same z (the (z, y, x) test); ghost rows below in z hold no neighbour.
    !> The order of each atom's neighbours is the order of the row-by-row scan.
    subroutine nl_build(self, atoms)
        class(neighbor_list_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        integer :: i, b, n, ntot, nlocal, bound, m1, m2, m3, nt
        real(dp) :: cutsq
        nlocal = atoms%nlocal
        if (self%want_clusters) then
            call self%clusters%build(atoms%x, nlocal, nlocal + atoms%nghost, self%cut)
            if (self%builds > 0) then
                call reserve(self%first, nlocal + 1)
                self%first(1:nlocal + 1) = 1
                self%max_neighbors = 0
                call self%hold(atoms)
                self%builds = self%builds + 1
                return
            end if
        end if
        ntot = product(self%nbin)
        cutsq = self%cutsq
        call prepare_build(self, atoms, bound)
        nt = self%type_order
        n = 0
        self%first(1) = 1
        associate (owned_start => self%owned_start, x => atoms%x)
        do b = 1, ntot
            if (owned_start(b + 1) == owned_start(b)) cycle
            call gather_candidates(self, b, nlocal, m1, m2, m3)
            do i = owned_start(b), owned_start(b + 1) - 1
                ! (+ 4: scan's four-lane stores may write three entries past the row's last)
                if (n + bound + 4 > size(self%neigh)) &
                    call grow_keep(self%neigh, n, n + bound + int(min(1.1_dp*n/max(i - 1, 1)*(nlocal - i + 1), &
                                                                     real(huge(1), dp)/4)))
                call owned_after(i, owned_start(b + 1) - 1, x, cutsq, self%neigh, n)
                call scan(x(1, i), x(2, i), x(3, i), self%cx, self%cy, self%cz, self%cj, self%keep, 1, m1, cutsq, &
                          .false., self%neigh, n)
                if (m2 > m1) call scan(x(1, i), x(2, i), x(3, i), self%cx, self%cy, self%cz, self%cj, self%keep, m1 + 1, &
                                       m2, cutsq, .true., self%neigh, n)
                if (m3 > m2) call scan(x(1, i), x(2, i), x(3, i), self%cx, self%cy, self%cz, self%cj, self%keep, m2 + 1, &
                                       m3, cutsq, .false., self%neigh, n)
                self%first(i + 1) = n + 1
                ! ordered by type while the row is in cache
                if (nt > 1) call order_row(self%neigh, self%first(i) - 1, n + 1 - self%first(i), atoms%type, nt, &
                                           self%tfirst((i - 1)*nt + 1:), self%tscratch)
            end do
        end do
        end associate
        if (nt > 1) self%tfirst(nt*nlocal + 1) = n + 1
        self%max_neighbors = longest_row(self%first, nlocal)
        call self%hold(atoms)
        if (self%want_below) call build_below(self, atoms)
        if (self%want_types) call neighbour_types(self, atoms%type, n)
        self%builds = self%builds + 1
    end subroutine nl_build

    !> Before a build: the ghosts sorted by bin, the positions in bin order, and room for the
    !> scratch rows (bound: the most candidates a bin's atoms can have), the row offsets, the
    !> type segments and the list (its expected length: half the atoms within the cutoff sphere at
    !> the mean density of the occupied bins, with a margin so that the list rarely has to grow, a
    !> copy and a memory peak).
    subroutine prepare_build(self, atoms, bound)
        class(neighbor_list_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        integer, intent(out) :: bound
        integer :: b, ntot, nall, nlocal, nghost, maxbin, c, need, occupied, nt
        real(dp) :: sphere, expect
        real(dp), parameter :: pi = 3.14159265358979324_dp
        nlocal = atoms%nlocal
        nghost = atoms%nghost
        nall = nlocal + nghost
        ntot = product(self%nbin)
        call reserve(self%atom_bin, max(nall, 1))
        call reserve(self%ghost_atoms, max(nghost, 1))
        call bin_sort(self, atoms%x, nlocal + 1, nall, self%ghost_start, self%ghost_atoms)
        maxbin = 0
        occupied = 0
        do b = 1, ntot
            c = self%owned_start(b + 1) - self%owned_start(b) + self%ghost_start(b + 1) - self%ghost_start(b)
            maxbin = max(maxbin, c)
            occupied = occupied + min(c, 1)
        end do
        bound = max(maxbin*self%stencil_bins, 1)
        if (self%dimension == 2) then
            sphere = pi*self%cutsq/(self%bin_size(1)*self%bin_size(2))
        else
            sphere = 4*pi/3*self%cutsq*self%cut/product(self%bin_size)
        end if
        expect = 0.5_dp*sphere*real(nall, dp)/max(occupied, 1)*nlocal
        call reserve(self%cx, bound)
        call reserve(self%cy, bound)
        call reserve(self%cz, bound)
        call reserve(self%keep, bound)
        call reserve(self%cj, bound)
        call bin_order_columns(self, atoms%x, nlocal, nghost)
        call reserve(self%first, nlocal + 1)
        nt = self%type_order
        if (nt > 1) then
            ! rows ordered by type: segments, and scratch as long as any row can be (bound)
            call reserve(self%tfirst, nt*nlocal + 1)
            if (allocated(self%tscratch)) then
                if (size(self%tscratch, 1) < bound + 1) deallocate (self%tscratch)
            end if
            if (.not. allocated(self%tscratch)) allocate (self%tscratch(bound + bound/4 + 16, 3))
        end if
        need = int(min(1.15_dp*expect + bound + 1024, real(huge(1), dp)/2))
        call reserve(self%neigh, need, exact=.true.)
    end subroutine prepare_build

    !> The candidates all atoms of bin b share, copied into the scratch rows cx, cy, cz, cj: 1..m1
    !> owned atoms of the rest of the centre row and of the upper rows; m1+1..m2 ghosts of the rows
    !> at the same z (centre row first), tested per atom in (z, y, x) order; m2+1..m3 ghosts of the
    !> rows above in z, all above.
    subroutine gather_candidates(self, b, nlocal, m1, m2, m3)
        class(neighbor_list_t), intent(inout) :: self
        integer, intent(in) :: b, nlocal
        integer, intent(out) :: m1, m2, m3
        integer :: r, cr
        cr = self%center_reach
        associate (owned_start => self%owned_start, ghost_start => self%ghost_start, row_lo => self%row_lo, &
                   row_hi => self%row_hi, row_dz => self%row_dz)
            m1 = 0
            call take_slots(owned_start(b + 1), owned_start(b + cr + 1) - 1, self%sx, self%sy, self%sz, self%sj, &
                            self%cx, self%cy, self%cz, self%cj, m1)
            do r = self%first_upper_row, self%nrows
                call take_slots(owned_start(b + row_lo(r)), owned_start(b + row_hi(r) + 1) - 1, self%sx, self%sy, &
                                self%sz, self%sj, self%cx, self%cy, self%cz, self%cj, m1)
            end do
            m2 = m1
            if (self%half_images) then
                ! every ghost of the whole stencil, none tested
                m3 = m2
                if (ghost_start(b + cr + 1) > ghost_start(b - cr)) &
                    call take_slots(nlocal + ghost_start(b - cr), nlocal + ghost_start(b + cr + 1) - 1, self%sx, &
                                    self%sy, self%sz, self%sj, self%cx, self%cy, self%cz, self%cj, m3)
                do r = 1, self%nrows
                    if (ghost_start(b + row_hi(r) + 1) == ghost_start(b + row_lo(r))) cycle
                    call take_slots(nlocal + ghost_start(b + row_lo(r)), nlocal + ghost_start(b + row_hi(r) + 1) - 1, &
                                    self%sx, self%sy, self%sz, self%sj, self%cx, self%cy, self%cz, self%cj, m3)
                end do
                return
            end if
            if (ghost_start(b + cr + 1) > ghost_start(b - cr)) &
                call take_slots(nlocal + ghost_start(b - cr), nlocal + ghost_start(b + cr + 1) - 1, self%sx, self%sy, &
                                self%sz, self%sj, self%cx, self%cy, self%cz, self%cj, m2)
            do r = 1, self%nrows
                if (row_dz(r) /= 0 .or. ghost_start(b + row_hi(r) + 1) == ghost_start(b + row_lo(r))) cycle
                call take_slots(nlocal + ghost_start(b + row_lo(r)), nlocal + ghost_start(b + row_hi(r) + 1) - 1, &
                                self%sx, self%sy, self%sz, self%sj, self%cx, self%cy, self%cz, self%cj, m2)
            end do
            m3 = m2
            do r = self%first_upper_row, self%nrows
                if (row_dz(r) <= 0 .or. ghost_start(b + row_hi(r) + 1) == ghost_start(b + row_lo(r))) cycle
                call take_slots(nlocal + ghost_start(b + row_lo(r)), nlocal + ghost_start(b + row_hi(r) + 1) - 1, &
                                self%sx, self%sy, self%sz, self%sj, self%cx, self%cy, self%cz, self%cj, m3)
            end do
        end associate
    end subroutine gather_candidates

    !> ntype(1:n) = type(neigh(1:n)), and eight pad entries of type 1 after them.
    subroutine neighbour_types(self, type, n)
        type(neighbor_list_t), intent(inout) :: self
        integer, intent(in) :: type(:), n
        call reserve(self%ntype, n + 8)
        call type_row(self%neigh, type, n, self%ntype)
    end subroutine neighbour_types

    !> The neighbours' types of a list built without them (want_types not set: lists made by hand
    !> in tests) into row, as ntype holds them: row(k) = type(neigh(k)) over the list of nlocal
    !> atoms, and eight pad entries of type 1. For passes that read list%ntype when want_types.
    subroutine gather_neighbour_types(list, type, nlocal, row)
        type(neighbor_list_t), intent(in) :: list
        integer, intent(in) :: type(:), nlocal
        integer, allocatable, intent(inout) :: row(:)
        integer :: n
        n = list%first(nlocal + 1) - 1
        call reserve(row, n + 8)
        call type_row(list%neigh, type, n, row)
    end subroutine gather_neighbour_types

    !> Order each row neigh(first(i) : first(i+1)-1) of the nlocal atoms by the neighbours' types
    !> 1..nt and set the segments tfirst(1 : nt*nlocal+1) as list%tfirst holds them (see
    !> order_row), for passes that need ordered rows of a list built without (type_order not set:
    !> lists made by hand in tests), on a copy of its neigh. scratch: at least the longest row + 1
    !> long, three columns.
    subroutine order_rows_by_type(first, neigh, type, nlocal, nt, tfirst, scratch)
        integer, intent(in) :: first(:), type(:), nlocal, nt
        integer, intent(inout) :: neigh(:), tfirst(:), scratch(:, :)
        integer :: i
        do i = 1, nlocal
            call order_row(neigh, first(i) - 1, first(i + 1) - first(i), type, nt, tfirst((i - 1)*nt + 1:), scratch)
        end do
        tfirst(nt*nlocal + 1) = first(nlocal + 1)
    end subroutine order_rows_by_type

    !> The row neigh(k0+1 : k0+nn) ordered by the neighbours' types 1..nt, the scan's order kept
    !> within a type; tfirst(b) = where the type-b neighbours start. The partners and their types
    !> into scratch(:, 1:2) (one gather of the types), then one branch-free compaction per type into
    !> scratch(:, 3), copied back. Placing each partner at its segment's next slot in one pass (a
    !> counting sort, or two types filled from both ends or after a count) was slower on the CuNi
    !> scene: neighbour builds 1.6 to 1.8 times those of the plain list, against 1.4 with this.
    subroutine order_row(neigh, k0, nn, type, nt, tfirst, scratch)
        integer, intent(in) :: k0, nn, type(:), nt
        integer, intent(inout) :: neigh(:), tfirst(:), scratch(:, :)
        integer :: k, j, t, n
        do k = 1, nn
            j = neigh(k0 + k)
            scratch(k, 1) = j
            scratch(k, 2) = type(j)
        end do
        n = 0
        do t = 1, nt
            tfirst(t) = k0 + n + 1
            do k = 1, nn
                scratch(n + 1, 3) = scratch(k, 1)
                n = n + merge(1, 0, scratch(k, 2) == t)
            end do
        end do
        neigh(k0 + 1:k0 + nn) = scratch(1:nn, 3)
    end subroutine order_row

    !> row(1:n) = type(neigh(1:n)), row(n+1 : n+8) = 1.
    pure subroutine type_row(neigh, type, n, row)
        integer, intent(in) :: neigh(:), type(:), n
        integer, intent(inout) :: row(:)
        integer :: k
        !GCC$ novector
        do k = 1, n
            row(k) = type(neigh(k))
        end do
        row(n + 1:n + 8) = 1
    end subroutine type_row

    !> The positions the displacement checks measure from (at every build; alone when the scene
    !> needs the rebuild schedule but no pair list).
    subroutine nl_hold(self, atoms)
        class(neighbor_list_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        integer :: nlocal
        nlocal = atoms%nlocal
        if (allocated(self%xhold)) then
            if (size(self%xhold, 2) < nlocal) deallocate (self%xhold)
        end if
        if (.not. allocated(self%xhold)) allocate (self%xhold(3, max(nlocal, 1) + nlocal/4))
        self%xhold(:, 1:nlocal) = atoms%x(:, 1:nlocal)
        self%scaled = 1
    end subroutine nl_hold

    !> The box and the positions were scaled by mu(d) about the origin, the list kept: the
    !> displacement reference follows (the owned atoms are those of the last build).
    subroutine nl_scale_reference(self, mu, nlocal)
        class(neighbor_list_t), intent(inout) :: self
        real(dp), intent(in) :: mu(3)
        integer, intent(in) :: nlocal
        integer :: i, d
        do i = 1, nlocal
            do d = 1, self%dimension
                self%xhold(d, i) = mu(d)*self%xhold(d, i)
            end do
        end do
        self%scaled = self%scaled*mu
    end subroutine nl_scale_reference

    !> The complement of the half list's ghost pairs: for each owned atom, the ghosts of the
    !> stencil rows below in z (all of them) and of the rows at the same z and the centre row
    !> (those not above it in (z, y, x) order, the half list's rule negated), within the cutoff.
    !> Every ghost of the full stencil is thus either in the half list or here, never both.
    !> Built at every rebuild when want_below (scalar: rebuild cost only).
    subroutine build_below(self, atoms)
        type(neighbor_list_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        integer :: i, b, r, n, nlocal, ntot, cr, need
        nlocal = atoms%nlocal
        ntot = product(self%nbin)
        cr = self%center_reach
        call reserve(self%below_first, nlocal + 1)
        need = max(self%first(nlocal + 1), 1024)
        call reserve(self%below, need, exact=.true.)
        n = 0
        self%below_first(1) = 1
        associate (owned_start => self%owned_start, ghost_start => self%ghost_start, row_lo => self%row_lo, &
                   row_hi => self%row_hi, row_dz => self%row_dz)
        do b = 1, ntot
            do i = owned_start(b), owned_start(b + 1) - 1
                call take(ghost_start(b - cr), ghost_start(b + cr + 1) - 1, .true.)
                do r = 1, self%nrows
                    if (row_dz(r) > 0) cycle
                    call take(ghost_start(b + row_lo(r)), ghost_start(b + row_hi(r) + 1) - 1, row_dz(r) == 0)
                end do
                self%below_first(i + 1) = n + 1
            end do
        end do
        end associate
        self%max_below = longest_row(self%below_first, nlocal)
    contains
        subroutine take(k1, k2, test_order)
            integer, intent(in) :: k1, k2
            logical, intent(in) :: test_order
            integer :: k, j
            real(dp) :: dx, dy, dz
            do k = k1, k2
                j = self%ghost_atoms(k)
                dx = atoms%x(1, j) - atoms%x(1, i); dy = atoms%x(2, j) - atoms%x(2, i)
                dz = atoms%x(3, j) - atoms%x(3, i)
                if (dx*dx + dy*dy + dz*dz >= self%cutsq) cycle
                if (test_order) then
                    if (dz > 0 .or. (dz == 0 .and. (dy > 0 .or. (dy == 0 .and. dx > 0)))) cycle
                end if
                if (n + 1 > size(self%below)) call grow_keep(self%below, n, 2*size(self%below))
                n = n + 1
                self%below(n) = j
            end do
        end subroutine take
    end subroutine build_below

    !> The longest of the n rows of a list laid out by first(1:n+1) (0 when n = 0).
    pure integer function longest_row(first, n) result(m)
        integer, intent(in) :: first(:), n
        integer :: i
        m = 0
        do i = 1, n
            m = max(m, first(i + 1) - first(i))
        end do
    end function longest_row

    !> Owned atoms after i in its own bin (i+1..last), within the cutoff.
    subroutine owned_after(i, last, x, cutsq, neigh, n)
        integer, intent(in) :: i, last
        real(dp), intent(in) :: x(3, *)
        real(dp), intent(in) :: cutsq
        integer, intent(inout), contiguous :: neigh(:)
        integer, intent(inout) :: n
        integer :: j
        real(dp) :: dx, dy, dz, rsq
        do j = i + 1, last
            dx = x(1, i) - x(1, j); dy = x(2, i) - x(2, j); dz = x(3, i) - x(3, j)
            rsq = dx*dx + dy*dy + dz*dz
            neigh(n + 1) = j
            if (rsq < cutsq) n = n + 1
        end do
    end subroutine owned_after

    !> Candidates k1..k2 of the shared rows within the cutoff of (xi, yi, zi) and, when above, also
    !> above it in (z, y, x) order (ghosts of the rows at the same z): with AVX-512 or AVX2
    !> scan_simd.c's masks and compressing stores, else 0/1 flags in one vectorised pass, then a
    !> branch-free compaction.
    subroutine scan(xi, yi, zi, cx, cy, cz, cj, keep, k1, k2, cutsq, above, neigh, n)
        real(dp), intent(in) :: xi, yi, zi, cutsq
        real(dp), intent(in), contiguous :: cx(:), cy(:), cz(:)
        integer, intent(inout), contiguous :: keep(:)
        integer, intent(in), contiguous :: cj(:)
        integer, intent(in) :: k1, k2
        logical, intent(in) :: above
        integer, intent(inout), contiguous :: neigh(:)
        integer, intent(inout) :: n
        integer :: k
        real(dp) :: dx, dy, dz
        k = c_scan_compress(xi, yi, zi, cx, cy, cz, cj, k1, k2, cutsq, merge(1, 0, above), neigh(n + 1:))
        if (k >= 0) then      ! (scan_simd.c did it: AVX-512 or AVX2)
            n = n + k
            return
        end if
        if (above) then
            do k = k1, k2
                dx = cx(k) - xi; dy = cy(k) - yi; dz = cz(k) - zi
                ! inside * (dz > 0 or (dz = 0 and (dy > 0 or (dy = 0 and dx > 0)))), without branches
                keep(k) = merge(1, 0, dx*dx + dy*dy + dz*dz < cutsq)* &
                          (merge(1, 0, dz > 0) + merge(1, 0, dz == 0)*(merge(1, 0, dy > 0) + &
                                                                       merge(1, 0, dy == 0)*merge(1, 0, dx > 0)))
            end do
        else
            do k = k1, k2
                dx = xi - cx(k); dy = yi - cy(k); dz = zi - cz(k)
                keep(k) = merge(1, 0, dx*dx + dy*dy + dz*dz < cutsq)
            end do
        end if
        do k = k1, k2
            neigh(n + 1) = cj(k)
            n = n + keep(k)
        end do
    end subroutine scan

    !> The bin-order columns sx, sy, sz, sj of the nlocal owned atoms (sorted by bin) and the nghost
    !> ghosts (in the order of ghost_atoms): once per build.
    subroutine bin_order_columns(self, x, nlocal, nghost)
        type(neighbor_list_t), intent(inout) :: self
        real(dp), intent(in) :: x(:, :)
        integer, intent(in) :: nlocal, nghost
        integer :: k, j, n
        n = max(nlocal + nghost, 1)
        call reserve(self%sx, n)
        call reserve(self%sy, n)
        call reserve(self%sz, n)
        call reserve(self%sj, n)
        do k = 1, nlocal
            self%sx(k) = x(1, k); self%sy(k) = x(2, k); self%sz(k) = x(3, k); self%sj(k) = k
        end do
        do k = 1, nghost
            j = self%ghost_atoms(k)
            self%sx(nlocal + k) = x(1, j); self%sy(nlocal + k) = x(2, j); self%sz(nlocal + k) = x(3, j)
            self%sj(nlocal + k) = j
        end do
    end subroutine bin_order_columns

    !> Append the slots first..last of the bin-order columns to the shared candidate rows (block
    !> copies).
    subroutine take_slots(first, last, sx, sy, sz, sj, cx, cy, cz, cj, m)
        integer, intent(in) :: first, last
        real(dp), intent(in), contiguous :: sx(:), sy(:), sz(:)
        integer, intent(in), contiguous :: sj(:)
        real(dp), intent(inout), contiguous :: cx(:), cy(:), cz(:)
        integer, intent(inout), contiguous :: cj(:)
        integer, intent(inout) :: m
        integer :: n
        n = last - first + 1
        if (n <= 0) return
        cx(m + 1:m + n) = sx(first:last); cy(m + 1:m + n) = sy(first:last); cz(m + 1:m + n) = sz(first:last)
        cj(m + 1:m + n) = sj(first:last)
        m = m + n
    end subroutine take_slots

    !> True on every rank if any owned atom anywhere moved more than skin/2 since the build.
    logical function nl_needs_rebuild(self, atoms) result(flag)
        class(neighbor_list_t), intent(in) :: self
        type(atoms_t), intent(in) :: atoms
        real(dp) :: half_skin
        ! a pair beyond rc + skin at the build is now beyond min(scaled) (rc + skin) less the two
        ! atoms' displacements from their scaled reference positions
        half_skin = 0.5_dp*(min(1.0_dp, minval(self%scaled(1:self%dimension)))*self%cut - (self%cut - self%skin))
        if (half_skin > 0) then
            flag = moved_too_far(atoms%nlocal, atoms%x, self%xhold, half_skin**2)
        else
            flag = .true.
        end if
        call any_all(flag)
    end function nl_needs_rebuild

    !> This list as the pairs of `outer` (a built list) within `cut` of each other now: each row of
    !> outer filtered in order. The pruned list (skin = cut - the outer list's cutoff without skin)
    !> holds every pair within that cutoff until an atom has moved skin/2 from here (expiry), as a
    !> list built with that skin would; energy stepping prunes far more often than it builds.
    subroutine nl_prune(self, outer, atoms, cut)
        class(neighbor_list_t), intent(inout) :: self
        type(neighbor_list_t), intent(in) :: outer
        type(atoms_t), intent(in) :: atoms
        real(dp), intent(in) :: cut
        integer :: i, n, nlocal, nt, g
        real(dp) :: cutsq
        nlocal = atoms%nlocal
        self%cut = cut
        self%cutsq = cut*cut
        self%skin = cut - (outer%cut - outer%skin)
        self%dimension = outer%dimension
        cutsq = self%cutsq
        self%want_types = outer%want_types
        self%type_order = outer%type_order
        call reserve(self%first, nlocal + 1)
        call reserve(self%neigh, outer%first(nlocal + 1) - 1 + 16)   ! (16: the fixed-point prune's whole stores)
        n = -1
        self%offs_build = -1
        if (.not. self%prune_reads_ghosts(outer)) then
            ! wrapped images: in fixed point from the owners, with the offsets (no ghost read)
            call reserve(self%ofirst, nlocal + 1)
            call reserve(self%offs, outer%first(nlocal + 1) - 1 + 16*nlocal + 32)
            call reserve(self%q, 4*nlocal + 4)
            n = c_prune_wrapped(nlocal, atoms%x, outer%wrap_box, self%q, outer%first, outer%neigh, outer%ofirst, &
                                outer%offs, cutsq, self%first, self%neigh, self%ofirst, self%offs)
            self%offs_build = merge(self%builds + 1, -1, n >= 0)
        end if
        if (n >= 0) then
            continue
        else if (self%type_order > 1) then
            n = 0
            self%first(1) = 1
            ! segment by segment: the rows stay ordered by type
            nt = self%type_order
            call reserve(self%tfirst, nt*nlocal + 1)
            do i = 1, nlocal
                do g = (i - 1)*nt + 1, i*nt
                    self%tfirst(g) = n + 1
                    call keep_within(atoms%x, i, outer%neigh, outer%tfirst(g), outer%tfirst(g + 1) - 1, cutsq, &
                                     self%neigh, n)
                end do
                self%first(i + 1) = n + 1
            end do
            self%tfirst(nt*nlocal + 1) = n + 1
        else
            n = 0
            self%first(1) = 1
            do i = 1, nlocal
                call keep_within(atoms%x, i, outer%neigh, outer%first(i), outer%first(i + 1) - 1, cutsq, self%neigh, n)
                self%first(i + 1) = n + 1
            end do
        end if
        if (self%want_types) call neighbour_types(self, atoms%type, n)
        self%max_neighbors = longest_row(self%first, nlocal)
        call self%hold(atoms)
        self%builds = self%builds + 1
    end subroutine nl_prune

    !> Whether a prune of this list from outer reads the ghosts' positions: not where outer has wrapped
    !> images with its offsets formed (wrap_offsets: the build has the fixed-point pass) and one row
    !> order (type_order <= 1, no types): the prune then reads the owners in fixed point (prune_simd.c,
    !> terrace_prune_wrapped) and also forms this list's offsets.
    pure logical function nl_prune_reads_ghosts(self, outer) result(reads)
        class(neighbor_list_t), intent(in) :: self
        type(neighbor_list_t), intent(in) :: outer
        reads = .not. (outer%wrapped .and. self%wrapped .and. outer%offs_build == outer%builds .and. &
                       outer%type_order <= 1 .and. .not. outer%want_types)
    end function nl_prune_reads_ghosts

    !> With wrapped images: this list's rows as byte offsets of the owners' records (row_offsets),
    !> for the fixed-point prune and the mixed-precision pass; offs_build = -1 where the build has no
    !> such pass.
    subroutine nl_wrap_offsets(self, nlocal)
        class(neighbor_list_t), intent(inout) :: self
        integer, intent(in) :: nlocal
        call reserve(self%ofirst, nlocal + 1)
        call reserve(self%offs, self%first(nlocal + 1) - 1 + 16*nlocal + 32)
        self%offs_build = -1
        if (row_offsets(nlocal, nlocal, self%first, self%neigh, .true., self%image_of, self%ofirst, self%offs)) &
            self%offs_build = self%builds
    end subroutine nl_wrap_offsets

    !> The rows (first, neigh) as byte offsets 16 (r - 1) of fixed-point records (row i at
    !> offs(ofirst(i) + 1 : ofirst(i + 1)), padded to 16 entries with the pad record's, 16 nrec): r the
    !> neighbour, or with wrapped its owner origin(neighbour). offs must hold first(nlocal + 1) - 1 +
    !> 15 nlocal entries. False (nothing done) where the build has no AVX-512 pass over such records.
    logical function row_offsets(nlocal, nrec, first, neigh, wrapped, origin, ofirst, offs) result(ok)
        integer, intent(in) :: nlocal, nrec
        integer, intent(in) :: first(:), neigh(:), origin(:)
        logical, intent(in) :: wrapped
        integer, intent(inout) :: ofirst(:), offs(:)
        ok = c_row_offsets(nlocal, nrec, first, neigh, merge(1, 0, wrapped), origin, ofirst, offs) >= 0
    end function row_offsets

    !> Append to neigh(n+1:) the partners neighbours(k1:k2) of atom i within cutsq, in order (with
    !> AVX-512 or AVX2 prune_simd.c's row loads and compressing stores, else a branch-free loop).
    subroutine keep_within(x, i, neighbours, k1, k2, cutsq, neigh, n)
        real(dp), intent(in) :: x(3, *)
        integer, intent(in) :: i, k1, k2
        integer, intent(in), contiguous :: neighbours(:)
        real(dp), intent(in) :: cutsq
        integer, intent(inout), contiguous :: neigh(:)
        integer, intent(inout) :: n
        integer :: k, j
        real(dp) :: xi, yi, zi, dx, dy, dz
        xi = x(1, i); yi = x(2, i); zi = x(3, i)
        if (k2 < k1) return
        k = c_prune_compress(xi, yi, zi, x, neighbours, k1, k2, cutsq, neigh(n + 1:))
        if (k >= 0) then      ! (prune_simd.c did it: AVX-512 or AVX2)
            n = n + k
            return
        end if
        do k = k1, k2
            j = neighbours(k)
            dx = xi - x(1, j); dy = yi - x(2, j); dz = zi - x(3, j)
            neigh(n + 1) = j
            n = n + merge(1, 0, dx*dx + dy*dy + dz*dz < cutsq)
        end do
    end subroutine keep_within

    !> Whether the list is rebuilt at this step (collective: the same answer on every rank). forced:
    !> a rebuild the caller needs anyway (a checkpoint). Exact schedule: when an atom has moved skin/2.
    !> Otherwise only at multiples of `every` (with check: when an atom has moved skin/2; without:
    !> always), and a rebuild at which an atom had moved skin/2 is counted in `late` (not with
    !> every = 1: a rebuild at every step leaves no step to an expired list).
    logical function nl_rebuild_due(self, atoms, step, forced) result(flag)
        class(neighbor_list_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        integer(i8), intent(in) :: step
        logical, intent(in) :: forced
        logical :: moved
        if (self%every == 1 .and. self%check) then
            flag = forced
            if (.not. flag) flag = self%needs_rebuild(atoms)
            return
        end if
        flag = forced .or. mod(step, int(self%every, i8)) == 0
        if (.not. flag) return
        moved = self%needs_rebuild(atoms)
        if (moved .and. self%every > 1) self%late = self%late + 1   ! (every = 1: no step used the expired list)
        if (self%check .and. .not. forced) flag = moved
    end function nl_rebuild_due

    !> True for the exact schedule (displacement test at every step).
    pure logical function nl_exact(self)
        class(neighbor_list_t), intent(in) :: self
        nl_exact = self%every == 1 .and. self%check
    end function nl_exact

    !> Earliest time (from now, this rank's atoms) at which an owned atom's displacement since the
    !> last build reaches skin/2, moving in a straight line: the root of |d + s v|^2 = (skin/2)^2.
    real(dp) function nl_expiry(self, atoms) result(t)
        class(neighbor_list_t), intent(in) :: self
        type(atoms_t), intent(in) :: atoms
        integer :: i, l, nb
        real(dp) :: r2, tl(8)
        r2 = (0.5_dp*self%skin)**2
        ! eight interleaved minima (vectorised, branch-free), then the tail
        tl = huge(1.0_dp)
        nb = (atoms%nlocal/8)*8
        do i = 1, nb, 8
            do l = 1, 8
                tl(l) = min(tl(l), exit_time(atoms%x(:, i + l - 1), self%xhold(:, i + l - 1), atoms%v(:, i + l - 1), r2))
            end do
        end do
        t = minval(tl)
        do i = nb + 1, atoms%nlocal
            t = min(t, exit_time(atoms%x(:, i), self%xhold(:, i), atoms%v(:, i), r2))
        end do
    end function nl_expiry

    !> Whether an owned atom has moved more than dist since the last build (or prune) (this rank).
    logical function nl_moved_beyond(self, atoms, dist) result(flag)
        class(neighbor_list_t), intent(in) :: self
        type(atoms_t), intent(in) :: atoms
        real(dp), intent(in) :: dist
        flag = moved_too_far(atoms%nlocal, atoms%x, self%xhold, dist*dist)
    end function nl_moved_beyond

    !> The time at which an atom at x moving with v reaches the distance sqrt(r2) from xhold: the
    !> positive root of a s^2 + 2 b s + c = 0 (a = |v|^2, b = d.v, c = |d|^2 - r2, d = x - xhold),
    !> without cancellation; 0 when it is there already, huge when it does not move. Branch-free.
    pure real(dp) function exit_time(x, xhold, v, r2) result(t)
        real(dp), intent(in) :: x(3), xhold(3), v(3), r2
        real(dp) :: d(3), a, b, c, sq, num, den
        d = x - xhold
        a = v(1)*v(1) + v(2)*v(2) + v(3)*v(3)
        b = d(1)*v(1) + d(2)*v(2) + d(3)*v(3)
        c = d(1)*d(1) + d(2)*d(2) + d(3)*d(3) - r2
        sq = sqrt(max(b*b - a*c, 0.0_dp))
        num = merge(-c, sq - b, b >= 0)
        den = merge(b + sq, a, b >= 0)
        t = merge(num/merge(den, 1.0_dp, den > 0), 0.0_dp, c < 0)
        t = merge(t, huge(1.0_dp), a > 0)       ! (an atom at rest never expires the list)
    end function exit_time

    !> Any of the n atoms displaced by more than sqrt(limit) from xhold: counted over all atoms
    !> in blocks (branch-free, vectorised), stopping after the first block that has one.
    logical function moved_too_far(n, x, xhold, limit) result(flag)
        integer, intent(in) :: n
        real(dp), intent(in) :: x(3, *), xhold(3, *), limit
        integer, parameter :: block = 512
        integer :: i, i0, far
        real(dp) :: dx, dy, dz
        flag = .false.
        do i0 = 1, n, block
            far = 0
            do i = i0, min(n, i0 + block - 1)
                dx = x(1, i) - xhold(1, i); dy = x(2, i) - xhold(2, i); dz = x(3, i) - xhold(3, i)
                far = far + merge(1, 0, dx*dx + dy*dy + dz*dz > limit)
            end do
            if (far > 0) then
                flag = .true.
                return
            end if
        end do
    end function moved_too_far

end module terrace_neighbor_list
