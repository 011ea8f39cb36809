!> Cluster-pair list (the layout of GROMACS's nbnxm kernels, Pall and Hess 2013): the atoms this
!> rank holds grouped into clusters of four, and for each cluster of owned atoms the clusters
!> (owned or ghost) with one of the 16 atom pairs within the list cutoff; a kernel then computes
!> all 4 x 4 pairs of a listed cluster pair as one 16-lane vector (terrace_lj_cluster).
!>
!> Clusters: the region of the atoms (owned and ghost) cut into square columns in x and y of
!> side about (4/rho)^(1/3) (four atoms per cube of that side); the owned atoms of a column sorted
!> by z and taken four at a time, then the ghosts of the column the same way (a cluster is all
!> owned or all ghost; its atoms in slots 1..nmem, the others empty, member = 0; a cluster closed
!> early when the next atom lies more than two sides above its first, so that sparse regions keep
!> small clusters). Each cluster has a centre on a grid of 2^-10 length units (so that the offset
!> between two centres is exact in single precision, as long as it is below 2^14 units) and a
!> half-width (its bounding box).
!>
!> Which pairs an owned cluster ci lists: the owned clusters cj >= ci (cj = ci: its own pairs,
!> i < j within the cluster, through mask 2), and the ghost clusters with at least one atom pair
!> that the atom list's rule gives to this rank (the ghost "above" the owned atom in (z, y, x)
!> order, terrace_neighbor_list): every pair once across ranks and periodic images. A listed
!> pair carries the offset of the centres (cj's minus ci's, single) and a mask: a row of `masks`,
!> 16 additions to the squared distance, 0 for a lane that counts and 1e30 (beyond any cutoff)
!> for one that does not (row 1: all count; row 2: within one cluster; rows from 3: ghost pairs
!> that the (z, y, x) rule splits). Each cluster's pairs with row 1 come first (masked_first).
!> Candidates (scan_columns): the columns within rlist of ci's box in x and y (owned clusters: the
!> half of the columns after ci's), in each the clusters whose z extent meets ci's widened by
!> rlist (a column's clusters ascend in z, and so do ci's: a pointer that only moves up), then the
!> atom check in single precision as the kernel forms the separations; a ghost cluster whose z
!> extent overlaps ci's is decided pair by pair by the rule, in double (split_pair).
module terrace_cluster_list
    use, intrinsic :: iso_fortran_env, only: sp => real32
    use terrace_kinds, only: dp
    use terrace_grow, only: reserve, grow_keep
    implicit none
    private

    !> The relative position of an empty slot on the j side (the i side uses -far_slot): empty
    !> slots are then beyond any cutoff from every atom and from each other.
    real(sp), parameter, public :: far_slot = -1.0e4_sp
    !> The largest cutoff (length units, exclusive) the cluster list and kernel serve: a tenth of
    !> |far_slot|, so that empty slots stay beyond the cutoff (larger cutoffs keep the atom list).
    real(dp), parameter, public :: cluster_cutoff_limit = 1000
    !> The squared-distance addition of a lane that does not count.
    real(sp), parameter, public :: masked = 1.0e30_sp

    !> Listed cluster pairs: for owned cluster ci, pairs first(ci) .. first(ci+1)-1, those from
    !> masked_first(ci) on with a mask row other than 1; cj the other cluster, offset the centres'
    !> offset (cj's minus ci's, single), mask the row of the list's masks.
    type, public :: cluster_pairs_t
        integer :: npairs = 0
        integer, allocatable :: first(:), masked_first(:), cj(:), mask(:)
        real(sp), allocatable :: offset(:, :)
    end type cluster_pairs_t

    !> The column grid of one build, as scan_columns reads it: the region's low corner in x and y,
    !> the columns' widths, the list cutoff and its square in single as the atom check compares it.
    type :: column_grid_t
        real(dp) :: lo(2), w(2), rlist
        real(sp) :: r2s
    end type column_grid_t

    !> One column of an owned column's stencil: its clusters first..last (first moves up to the
    !> first whose top is above the current owned cluster's bottom - rlist: the owned clusters
    !> ascend in z), its place (tx, ty) in the grid, whether its clusters are ghosts, whether it is
    !> the owned cluster's own column (only the clusters after it).
    type :: stencil_column_t
        integer :: first, last, tx, ty
        logical :: ghost, same
    end type stencil_column_t

    !> The owned cluster whose candidates scan_columns finds: its index, its slots spread over the
    !> 16 lanes relative to its centre (single; empty slots at -far_slot), its bounding box and the
    !> z extent of its atoms.
    type :: owned_cluster_t
        integer :: ci
        real(sp) :: xi(16, 3)
        real(dp) :: box_lo(3), box_hi(3), zlo, zhi
    end type owned_cluster_t

    type, public :: cluster_list_t
        integer :: nowned = 0          !< clusters of owned atoms (1 .. nowned); ghost clusters after them
        integer :: ncl = 0             !< all clusters
        integer :: nmasks = 2
        integer, allocatable :: member(:, :)     !< (4, ncl): atom index of each slot, 0 = empty
        integer, allocatable :: nmem(:)          !< (ncl): atoms in the cluster (slots 1..nmem; 4: full)
        real(dp), allocatable :: centre(:, :)    !< (3, ncl)
        type(cluster_pairs_t) :: pairs           !< the list (built at rlist)
        real(sp), allocatable :: masks(:, :)     !< (16, nmasks)
        ! build scratch
        real(dp), allocatable :: half(:, :), zlo(:), zhi(:)
        real(sp), allocatable :: xq(:, :, :)     !< (16, 3, ncl): replicated positions at the build
        integer, allocatable :: col(:), order(:), cstart(:), ccount(:), ofirst(:), gfirst(:)
        integer, allocatable :: split(:)         !< ghost clusters of one owned cluster for split_pair
    contains
        procedure :: build => cl_build
        procedure :: replicate_positions
    end type cluster_list_t

contains

    !> The clusters and their list from the positions x of nlocal owned atoms and the ghosts after
    !> them (nall in all), for the list cutoff rlist (3-D).
    subroutine cl_build(self, x, nlocal, nall, rlist)
        class(cluster_list_t), intent(inout) :: self
        real(dp), intent(in) :: x(:, :), rlist
        integer, intent(in) :: nlocal, nall
        real(dp) :: lo(3), hi(3), ext(3), rho, side, w(2), zcap
        integer :: ncx, ncy, ncol, i, c, rx, ry, nco, ncg, n
        lo = huge(1.0_dp); hi = -huge(1.0_dp)
        do i = 1, nall
            lo = min(lo, x(:, i)); hi = max(hi, x(:, i))
        end do
        if (nall == 0) then
            lo = 0; hi = 1
        end if
        ext = max(hi - lo, 1e-3_dp*rlist)
        rho = real(max(nall, 1), dp)/product(ext)
        side = (4/rho)**(1.0_dp/3)
        ncx = max(1, min(int(ext(1)/side), 4096)); ncy = max(1, min(int(ext(2)/side), 4096))
        w = [ext(1)/ncx, ext(2)/ncy]
        ! atoms in columns i and i + r can be within rlist only if (r - 1) w < rlist
        rx = min(ncx - 1, int(rlist/w(1)) + 1); ry = min(ncy - 1, int(rlist/w(2)) + 1)
        ncol = ncx*ncy
        call reserve(self%col, max(nall, 1))
        call reserve(self%order, max(nall, 1))
        call reserve(self%cstart, 2*ncol + 1)
        call reserve(self%ccount, 2*ncol)
        call reserve(self%ofirst, ncol + 1)
        call reserve(self%gfirst, ncol + 1)
        ! columns: owned atoms in 1..ncol, ghosts in ncol+1..2 ncol (one counting sort)
        self%ccount(1:2*ncol) = 0
        do i = 1, nall
            c = 1 + min(ncx - 1, int((x(1, i) - lo(1))/w(1))) + ncx*min(ncy - 1, int((x(2, i) - lo(2))/w(2)))
            if (i > nlocal) c = c + ncol
            self%col(i) = c
            self%ccount(c) = self%ccount(c) + 1
        end do
        self%cstart(1) = 1
        do c = 1, 2*ncol
            self%cstart(c + 1) = self%cstart(c) + self%ccount(c)
        end do
        self%ccount(1:2*ncol) = 0
        do i = 1, nall
            c = self%col(i)
            self%order(self%cstart(c) + self%ccount(c)) = i
            self%ccount(c) = self%ccount(c) + 1
        end do
        do c = 1, 2*ncol
            call sort_by_z(self%order, self%cstart(c), self%cstart(c + 1) - 1, x)
        end do
        ! clusters: the owned columns' first, then the ghost columns'
        ! clusters (four atoms, fewer where a column is sparse: a cluster spans at most zcap in z,
        ! so that relative positions stay small), the owned columns' first, then the ghost columns'
        zcap = 2*side
        nco = 0
        do c = 1, ncol
            self%ofirst(c) = nco + 1
            nco = nco + column_clusters(self, x, self%cstart(c), self%cstart(c + 1) - 1, zcap, 0)
        end do
        self%ofirst(ncol + 1) = nco + 1
        ncg = nco
        do c = 1, ncol
            self%gfirst(c) = ncg + 1
            ncg = ncg + column_clusters(self, x, self%cstart(ncol + c), self%cstart(ncol + c + 1) - 1, zcap, 0)
        end do
        self%gfirst(ncol + 1) = ncg + 1
        self%nowned = nco
        self%ncl = ncg
        call size_clusters(self)
        do c = 1, ncol
            n = column_clusters(self, x, self%cstart(c), self%cstart(c + 1) - 1, zcap, self%ofirst(c))
            n = column_clusters(self, x, self%cstart(ncol + c), self%cstart(ncol + c + 1) - 1, zcap, self%gfirst(c))
        end do
        call list_pairs(self, x, ncx, ncy, rx, ry, rlist, lo, w)
    end subroutine cl_build

    !> Room for ncl clusters (and the first rows of masks).
    subroutine size_clusters(self)
        type(cluster_list_t), intent(inout) :: self
        integer :: n, l
        n = max(self%ncl, 1)
        if (allocated(self%member)) then
            if (size(self%member, 2) < n) deallocate (self%member, self%nmem, self%centre, self%half, self%zlo, self%zhi, self%xq)
        end if
        if (.not. allocated(self%member)) then
            n = n + n/4
            allocate (self%member(4, n), self%nmem(n), self%centre(3, n), self%half(3, n), self%zlo(n), self%zhi(n), &
                      self%xq(16, 3, n))
        end if
        call reserve(self%pairs%first, self%nowned + 1)
        call reserve(self%pairs%masked_first, max(self%nowned, 1))
        if (.not. allocated(self%masks)) allocate (self%masks(16, 64))
        self%masks(:, 1) = 0
        do l = 1, 16      ! lane l pairs atom (l - 1)/4 + 1 of ci with atom mod(l - 1, 4) + 1 of cj
            self%masks(l, 2) = merge(0.0_sp, masked, ishft(l - 1, -2) < mod(l - 1, 4))
        end do
        self%nmasks = 2
    end subroutine size_clusters

    !> The atoms order(k1:k2) (one column, sorted by z) taken as clusters of four, a cluster closed
    !> early when the next atom lies more than zcap above its first (sparse columns); returns how
    !> many. With c0 > 0 it also fills clusters c0, c0 + 1, ...: members (0 for an empty slot),
    !> centres on the 2^-10 grid, half-widths, z extents.
    integer function column_clusters(self, x, k1, k2, zcap, c0) result(nc)
        type(cluster_list_t), intent(inout) :: self
        real(dp), intent(in) :: x(:, :), zcap
        integer, intent(in) :: k1, k2, c0
        integer :: k, s, c, a, m
        real(dp) :: lo(3), hi(3), z0
        nc = 0
        k = k1
        do while (k <= k2)
            z0 = x(3, self%order(k))
            m = 1
            do while (m < 4 .and. k + m <= k2)
                if (x(3, self%order(k + m)) - z0 > zcap) exit
                m = m + 1
            end do
            nc = nc + 1
            if (c0 > 0) then
                c = c0 + nc - 1
                lo = huge(1.0_dp); hi = -huge(1.0_dp)
                do s = 1, 4
                    a = 0
                    if (s <= m) a = self%order(k + s - 1)
                    self%member(s, c) = a
                    self%nmem(c) = m
                    if (a > 0) then
                        lo = min(lo, x(:, a)); hi = max(hi, x(:, a))
                    end if
                end do
                self%centre(:, c) = anint(0.5_dp*(lo + hi)*1024)/1024
                self%half(:, c) = max(hi - self%centre(:, c), self%centre(:, c) - lo)
                self%zlo(c) = lo(3); self%zhi(c) = hi(3)
            end if
            k = k + m
        end do
    end function column_clusters

    !> Insertion sort of order(k1:k2) by z (a column's owned atoms arrive nearly sorted: the atoms
    !> are sorted by bin, and the bins by z first).
    subroutine sort_by_z(order, k1, k2, x)
        integer, intent(inout) :: order(:)
        integer, intent(in) :: k1, k2
        real(dp), intent(in) :: x(:, :)
        integer :: k, kk, m
        do k = k1 + 1, k2
            m = order(k); kk = k - 1
            do while (kk >= k1)
                if (x(3, order(kk)) <= x(3, m)) exit
                order(kk + 1) = order(kk); kk = kk - 1
            end do
            order(kk + 1) = m
        end do
    end subroutine sort_by_z

    !> The list: for each owned cluster, its own pairs, the owned clusters after it (its own
    !> column and the half of the columns within reach that come after it) and the ghost
    !> clusters of all columns within reach, that pass the box and atom checks. In each stencil
    !> column the candidates are the clusters whose z extent meets ci's widened by rlist: a column's
    !> clusters ascend in z, and so do ci's, so the first candidate only moves up (ptr).
    subroutine list_pairs(self, x, ncx, ncy, rx, ry, rlist, lo, w)
        type(cluster_list_t), intent(inout) :: self
        real(dp), intent(in) :: x(:, :), rlist, lo(3), w(2)
        integer, intent(in) :: ncx, ncy, rx, ry
        integer :: ci, c, ix, iy, jx, jy, m, n, nt
        type(stencil_column_t) :: cols(2*(2*rx + 1)*(2*ry + 1))
        type(column_grid_t) :: grid
        type(owned_cluster_t) :: own
        real(dp) :: r2list, xd(4, 3)
        integer :: bound, nsplit, l
        r2list = rlist*rlist
        grid%lo = lo(1:2); grid%w = w; grid%rlist = rlist
        grid%r2s = real(r2list, sp)*(1 + 8*epsilon(1.0_sp))   ! single rounding never drops a pair
        call replicate_positions(self, x, self%xq)
        call reserve(self%split, max(self%ncl, 1))   ! (a cluster is a split candidate of ci at most once)
        n = 0
        call reserve(self%pairs%cj, 32*self%nowned + 64)
        call reserve(self%pairs%mask, size(self%pairs%cj))
        if (allocated(self%pairs%offset)) then
            if (size(self%pairs%offset, 2) < size(self%pairs%cj)) deallocate (self%pairs%offset)
        end if
        if (.not. allocated(self%pairs%offset)) allocate (self%pairs%offset(3, size(self%pairs%cj)))
        do c = 1, ncx*ncy
            if (self%ofirst(c + 1) == self%ofirst(c)) cycle
            ix = mod(c - 1, ncx); iy = (c - 1)/ncx
            nt = 0
            do jy = max(0, iy - ry), min(ncy - 1, iy + ry)
                do jx = max(0, ix - rx), min(ncx - 1, ix + rx)
                    m = 1 + jx + ncx*jy
                    if (m >= c .and. self%ofirst(m + 1) > self%ofirst(m)) then     ! owned: the half ahead
                        nt = nt + 1
                        cols(nt) = stencil_column_t(self%ofirst(m), self%ofirst(m + 1) - 1, jx, jy, .false., m == c)
                    end if
                    if (self%gfirst(m + 1) > self%gfirst(m)) then
                        nt = nt + 1
                        cols(nt) = stencil_column_t(self%gfirst(m), self%gfirst(m + 1) - 1, jx, jy, .true., .false.)
                    end if
                end do
            end do
            bound = 1
            do l = 1, nt
                bound = bound + cols(l)%last - cols(l)%first + 1
            end do
            do ci = self%ofirst(c), self%ofirst(c + 1) - 1
                self%pairs%first(ci) = n + 1
                call room(self, n + bound)
                nsplit = 0
                call owned_cluster(self, ci, own)
                call scan_columns(own, grid, nt, cols, self%centre, self%zlo, self%zhi, self%xq, self%pairs%cj, &
                                  self%pairs%mask, self%pairs%offset, n, self%split, nsplit)
                self%pairs%masked_first(ci) = n + 1
                if (self%nmem(ci) > 1) call add(self, ci, ci, 2, n)   ! its own pairs (i < j)
                if (nsplit > 0) then
                    do l = 1, 4      ! ci's atoms in double (the split rule); an empty slot far below
                        xd(l, :) = -1.0e100_dp     ! (squares stay finite: no overflow)
                        if (self%member(l, ci) > 0) xd(l, :) = x(:, self%member(l, ci))
                    end do
                    do l = 1, nsplit
                        call split_pair(self, x, ci, self%split(l), xd, r2list, n)
                    end do
                end if
            end do
        end do
        self%pairs%first(self%nowned + 1) = n + 1
        self%pairs%npairs = n
    end subroutine list_pairs

    !> Owned cluster ci as scan_columns reads it: its slots over the 16 lanes (i0 i0 i0 i0 i1 ...,
    !> from the replicated positions; an empty slot at -far_slot), its box and its z extent.
    subroutine owned_cluster(self, ci, own)
        type(cluster_list_t), intent(in) :: self
        integer, intent(in) :: ci
        type(owned_cluster_t), intent(out) :: own
        integer :: l
        own%ci = ci
        do l = 1, 16
            own%xi(l, :) = self%xq(ishft(l - 1, -2) + 1, :, ci)
            if (self%member(ishft(l - 1, -2) + 1, ci) == 0) own%xi(l, :) = -far_slot
        end do
        own%box_lo = self%centre(:, ci) - self%half(:, ci); own%box_hi = self%centre(:, ci) + self%half(:, ci)
        own%zlo = self%zlo(ci); own%zhi = self%zhi(ci)
    end subroutine owned_cluster

    !> The candidates of owned cluster own%ci in its nt stencil columns (clusters first..last of
    !> column t; ghost clusters or owned; in ci's own column only the clusters after ci): the
    !> columns within rlist of ci's box in x and y, in each the clusters whose z extent meets ci's
    !> widened by rlist, then the atom check (any of the 16 pairs within rlist, in singles as the
    !> kernel forms them).
    !> A kept pair is written in slot n + 1 and kept by advancing n (no branch); ghost clusters whose
    !> z extent overlaps ci's go to split (the (z, y, x) rule decides per pair, split_pair).
    !> cols(t)%first moves up to the first cluster whose top is above ci's bottom - rlist.
    !> Explicit arrays, not the list's components: GCC then keeps their addresses in registers.
    subroutine scan_columns(own, grid, nt, cols, centre, zlo, zhi, xq, cjs, mask, offset, n, split, nsplit)
        type(owned_cluster_t), intent(in) :: own
        type(column_grid_t), intent(in) :: grid
        integer, intent(in) :: nt
        type(stencil_column_t), intent(inout) :: cols(nt)
        real(dp), intent(in) :: centre(3, *), zlo(*), zhi(*)
        real(sp), intent(in) :: xq(16, 3, *)
        integer, intent(inout) :: cjs(*), mask(*), n, split(*), nsplit
        real(sp), intent(inout) :: offset(3, *)
        integer :: t, ci, cj, l, near, j1, j2, ptr, last
        real(dp) :: za, zb, e(2), r2list, rlist, ci_lo(3), ci_hi(3), ci_zlo, ci_zhi, lo(2), w(2)
        real(sp) :: xi(16, 3), o(3), q, r2s
        ci = own%ci
        rlist = grid%rlist; r2s = grid%r2s; lo = grid%lo; w = grid%w
        r2list = rlist*rlist
        ci_lo = own%box_lo; ci_hi = own%box_hi
        xi = own%xi
        ci_zlo = own%zlo; ci_zhi = own%zhi
        za = ci_zlo - rlist; zb = ci_zhi + rlist
        do t = 1, nt
            ptr = cols(t)%first; last = cols(t)%last
            do while (ptr <= last)
                if (zhi(ptr) > za) exit
                ptr = ptr + 1
            end do
            cols(t)%first = ptr
            ! columns whose rectangle in x and y lies beyond rlist from ci's box hold no pair (a
            ! tighter z window from this distance cost more, by its square root, than it saved)
            e(1) = max(lo(1) + cols(t)%tx*w(1) - ci_hi(1), ci_lo(1) - (lo(1) + (cols(t)%tx + 1)*w(1)), 0.0_dp)
            e(2) = max(lo(2) + cols(t)%ty*w(2) - ci_hi(2), ci_lo(2) - (lo(2) + (cols(t)%ty + 1)*w(2)), 0.0_dp)
            if (e(1)*e(1) + e(2)*e(2) >= r2list*(1 + 1e-9_dp)) cycle
            ! the window j1..j2 (no box check: the atom check decides, and the branch of a box
            ! check cost more than the atom checks it saved)
            j1 = ptr
            if (cols(t)%same) j1 = max(j1, ci + 1)
            j2 = j1 - 1
            do while (j2 < last)
                if (zlo(j2 + 1) >= zb) exit
                j2 = j2 + 1
            end do
            if (.not. cols(t)%ghost) then
                do cj = j1, j2
                    include 'cluster_atom_check.inc'
                    cjs(n + 1) = cj; mask(n + 1) = 1; offset(:, n + 1) = o
                    n = n + min(near, 1)
                end do
            else
                do cj = j1, j2
                    if (zhi(cj) < ci_zlo) cycle       ! every ghost below every atom of ci
                    include 'cluster_atom_check.inc'
                    if (near > 0 .and. zlo(cj) <= ci_zhi) then      ! the (z, y, x) rule may split it
                        nsplit = nsplit + 1
                        split(nsplit) = cj
                        cycle
                    end if
                    cjs(n + 1) = cj; mask(n + 1) = 1; offset(:, n + 1) = o
                    n = n + min(near, 1)
                end do
            end if
        end do
    end subroutine scan_columns

    !> Room for n listed pairs.
    subroutine room(self, n)
        type(cluster_list_t), intent(inout) :: self
        integer, intent(in) :: n
        real(sp), allocatable :: t(:, :)
        integer :: keep, m
        if (n <= size(self%pairs%cj)) return
        keep = size(self%pairs%cj)
        m = max(n, keep + keep/2)
        call grow_keep(self%pairs%cj, keep, m)
        call grow_keep(self%pairs%mask, keep, m)
        allocate (t(3, size(self%pairs%cj)))
        t(:, 1:keep) = self%pairs%offset(:, 1:keep)
        call move_alloc(t, self%pairs%offset)
    end subroutine room

    !> Listed pair n + 1: ci with cj, mask row mrow.
    subroutine add(self, ci, cj, mrow, n)
        type(cluster_list_t), intent(inout) :: self
        integer, intent(in) :: ci, cj, mrow
        integer, intent(inout) :: n
        n = n + 1
        self%pairs%cj(n) = cj
        self%pairs%mask(n) = mrow
        self%pairs%offset(:, n) = real(self%centre(:, cj) - self%centre(:, ci), sp)
    end subroutine add

    !> Owned cluster ci (its atoms at xd, empty slots far below) and a ghost cluster cj whose z
    !> extents overlap: each atom pair counts here when the ghost is above the owned atom in
    !> (z, y, x) order (the atom list's rule, in double from the positions, as the owner of the
    !> ghost decides the mirrored pair); listed when a counted pair lies within rlist, with a mask
    !> row when some pairs do not count. Empty slots count (they are beyond any cutoff).
    subroutine split_pair(self, x, ci, cj, xd, r2list, n)
        type(cluster_list_t), intent(inout) :: self
        real(dp), intent(in) :: x(:, :), xd(4, 3), r2list
        integer, intent(in) :: ci, cj
        integer, intent(inout) :: n
        integer :: b, l, ja, na, nn
        real(dp) :: xj(4, 3), ai(16, 3), aj(16, 3), dx, dy, dz
        integer :: ok(16)
        do b = 1, 4
            ja = self%member(b, cj)
            xj(b, :) = 1.0e100_dp       ! an empty ghost slot: far above (counts, never near; squares finite)
            if (ja > 0) xj(b, :) = x(:, ja)
        end do
        do l = 1, 16      ! the 16 lanes' atoms side by side (then one vectorised pass)
            ai(l, :) = xd(ishft(l - 1, -2) + 1, :)
            aj(l, :) = xj(iand(l - 1, 3) + 1, :)
        end do
        na = 0; nn = 0
        do l = 1, 16
            dx = aj(l, 1) - ai(l, 1); dy = aj(l, 2) - ai(l, 2); dz = aj(l, 3) - ai(l, 3)
            ok(l) = merge(1, 0, dz > 0) + merge(1, 0, dz == 0)*(merge(1, 0, dy > 0) + merge(1, 0, dy == 0)*merge(1, 0, dx > 0))
            na = na + ok(l)
            nn = nn + ok(l)*merge(1, 0, dx*dx + dy*dy + dz*dz < r2list)
        end do
        if (nn == 0) return
        if (na == 16) then
            call add(self, ci, cj, 1, n)
        else
            if (self%nmasks == size(self%masks, 2)) call grow_masks(self)
            self%nmasks = self%nmasks + 1
            self%masks(:, self%nmasks) = merge(0.0_sp, masked, ok == 1)
            call add(self, ci, cj, self%nmasks, n)
        end if
    end subroutine split_pair

    !> xrep(l, :, c): slot mod(l - 1, 4) + 1 of cluster c relative to its centre, rounded to
    !> single (far_slot for an empty slot): the j side of the kernel's 16 lanes (j0 j1 j2 j3 j0 ...).
    subroutine replicate_positions(self, x, xrep)
        class(cluster_list_t), intent(in) :: self
        real(dp), intent(in) :: x(:, :)
        real(sp), intent(inout), contiguous :: xrep(:, :, :)
        call replicate_records(self%ncl, self%nmem, self%member, self%centre, x, xrep)
    end subroutine replicate_positions

    !> replicate_positions over explicit arrays (full clusters without a test per slot)
    subroutine replicate_records(ncl, nmem, member, centre, x, xrep)
        integer, intent(in) :: ncl, nmem(*), member(4, *)
        real(dp), intent(in) :: centre(3, *), x(:, :)
        real(sp), intent(inout) :: xrep(16, 3, *)
        integer :: c, s, a
        real(sp) :: r(4, 3)
        do c = 1, ncl
            if (nmem(c) == 4) then
                do s = 1, 4
                    r(s, :) = real(x(:, member(s, c)) - centre(:, c), sp)
                end do
            else
                do s = 1, 4
                    a = member(s, c)
                    r(s, :) = far_slot
                    if (a > 0) r(s, :) = real(x(:, a) - centre(:, c), sp)
                end do
            end if
            xrep(1:4, :, c) = r; xrep(5:8, :, c) = r; xrep(9:12, :, c) = r; xrep(13:16, :, c) = r
        end do
    end subroutine replicate_records

    subroutine grow_masks(self)
        type(cluster_list_t), intent(inout) :: self
        real(sp), allocatable :: t(:, :)
        allocate (t(16, 2*size(self%masks, 2)))
        t(:, 1:self%nmasks) = self%masks(:, 1:self%nmasks)
        call move_alloc(t, self%masks)
    end subroutine grow_masks

end module terrace_cluster_list
