!> Embedded-atom method (pair_style eam, eam/alloy, eam/fs of LAMMPS), from tabulated files.
!>
!>   E = sum_i F_a(rho_i) + 1/2 sum_i sum_{j /= i} phi_ab(r_ij),   rho_i = sum_{j /= i} rho_ba(r_ij)
!>
!> with a the element of atom i, b that of j, and rho_ba(r) the density an atom of element b puts at
!> an atom of element a (eam, eam/alloy: rho_b(r), one function per element; eam/fs: one function
!> per ordered pair, listed in the file section of b, in the order of a). The force on i from the
!> pair (i, j), d = x_i - x_j, r = |d|, is
!>   F_i = -[ F'_a(rho_i) rho_ba'(r) + F'_b(rho_j) rho_ab'(r) + phi_ab'(r) ] d/r = -F_j.
!> The work is split as the engine needs it in parallel: `density` sums rho over the half list
!> (ghosts included, the caller reverse-sums ghost rho into the owners), `embed` evaluates F and
!> fp = F'(rho) of owned atoms (the caller forwards fp to ghosts), `force` adds the pair forces.
!> For energy stepping, `ray` returns V, V', V'' and the virial along x + s v with no communication
!> (it needs the neighbour list's complement of ghost partners, list%want_below; see eam_ray).
!> The density and force kernels are staged for vectorisation (see density_one); with several
!> types the passes take the list's rows ordered by type (neighbour_type_order) segment by
!> segment, the tables of each segment's type pair fixed for it (see build_pair_tables).
!>
!> Tables and interpolation as LAMMPS (so that energies and forces agree to round-off):
!> - Grids: rho_k = (k-1) drho, k = 1..nrho, for F; r_k = (k-1) dr, k = 1..nr, for rho(r) and
!>   z(r) = r phi(r). setfl/fs files are used on their own grid. funcfl files (which tabulate
!>   F(rho), the effective charge Z(r) and rho(r)) are resampled onto a common grid:
!>   dr = max dr_f, drho = max drho_f, nr = int(max_f (nr_f-1) dr_f / dr + 0.5),
!>   nrho = int(max_f (nrho_f-1) drho_f / drho + 0.5) (for one file this drops its last knot), by
!>   4-point Lagrange interpolation in the file's knots k-1..k+2 (k clamped to 2..n_f-2, the offset
!>   to [., 2]), and z_ab(r) = 27.2 * 0.529 Z_a(r) Z_b(r) (Hartree * Bohr in eV Angstrom).
!>   The embedding extrapolation threshold rhomax is max_f (nrho_f-1) drho_f (funcfl) or
!>   (nrho-1) drho (setfl/fs); the cutoff is max_f cut_f (funcfl) or the file's cutoff.
!> - Each table y_1..y_n of spacing h becomes cubic pieces y(p) = ((c3 p + c4) p + c5) p + y_m on
!>   [x_m, x_m+1], p = (x - x_m)/h, with knot slopes (per knot) c5_1 = y_2 - y_1,
!>   c5_2 = (y_3 - y_1)/2, c5_m = (y_{m-2} - y_{m+2} + 8 (y_{m+1} - y_{m-1}))/12 (3 <= m <= n-2),
!>   c5_{n-1} = (y_n - y_{n-2})/2, c5_n = y_n - y_{n-1}, and c4 = 3 dy - 2 c5_m - c5_{m+1},
!>   c3 = c5_m + c5_{m+1} - 2 dy (dy = y_{m+1} - y_m): C1 Hermite pieces through the knots. The
!>   derivative is (c0 p + c1) p + c2 with c2 = c5/h, c1 = 2 c4/h, c0 = 3 c3/h. Stored per knot
!>   as s(1:7, m) = c0, c1, c2, c3, c4, c5, y_m.
!> - Lookup at x: p = x/h + 1, m = int(p) clamped to [1, n-1], p = min(p - m, 1). Beyond the last
!>   knot the value is held (r) and the slope is that of the last piece's end; below the first
!>   knot (rho < 0) the first piece is extrapolated. For rho > rhomax the embedding energy is
!>   continued linearly, F(rhomax) + F'(rhomax) (rho - rhomax) (the force uses the held slope);
!>   `rho_outside` records that this happened (see `warning`).
!> - Pairs count when r^2 < cutmax^2.
!> - V is summed per atom (pair energies of its pairs; its embedding energy) and the per-atom sums
!>   are added with a compensated sum, in the force and in the ray pass: the energy-stepping
!>   solver decides on V to a few tens of eps |V| (terrace_compensated_sum says why).
!> This file holds the type, the file tables and their splines; the force passes (with the tables
!> they read) are eam_force.inc, the ray pass eam_ray.inc (included below: one compilation unit),
!> the AVX-512 density gather eam_simd.c.
module terrace_eam
    use, intrinsic :: iso_c_binding, only: c_loc, c_intptr_t, c_int, c_double
    use terrace_kinds, only: dp
    use terrace_compensated_sum, only: comp_add
    use terrace_atoms, only: atoms_t
    use terrace_grow, only: reserve
    use terrace_neighbor_list, only: neighbor_list_t, order_rows_by_type, longest_row
    use terrace_eam_files, only: eam_file_t, read_funcfl_file, read_setfl_file
    use terrace_potential, only: potential_t, halo_ops_t, max_warning_flags
    implicit none
    private

    !> Pairs per block of the force passes (rows of about this length, several atoms each).
    integer, parameter :: block_pairs = 256

    !> Hartree * Bohr (eV Angstrom) as LAMMPS writes it: phi = 27.2 * 0.529 Z_a Z_b / r for funcfl.
    real(dp), parameter, public :: funcfl_z2r_factor = 27.2_dp*0.529_dp

    type, extends(potential_t), public :: eam_t
        integer :: ntypes = 0
        character(len=:), allocatable :: file_name  !< for the scene plan
        real(dp), allocatable :: halo_buf(:, :)     !< one-component copies of rho / F'(rho) for the halo
        real(dp) :: cutmax = 0                      !< largest cutoff (Angstrom)
        real(dp), allocatable :: mass(:)            !< per atom type, from the file (amu)
        real(dp), allocatable :: rho(:)             !< per atom (owned + ghost), electron density
        real(dp), allocatable :: fp(:)              !< per atom (owned + ghost), F'(rho)
        real(dp), allocatable :: ray_acc(:, :)      !< ray pass: (rho, rho', rho'', sum r f') per owned atom
        real(dp), allocatable :: work(:, :)         !< one-type kernels: per-neighbour rows of the current atom
        integer, allocatable :: iwork(:, :)         !< one-type kernels: compacted neighbour indices and knots
        real(dp), allocatable :: ztab(:, :)         !< one type: (rho' c0..c2, z c3..c6) per r knot
        real(dp), allocatable :: rtab(:)            !< one type: density records (rho c3..c6) per r knot
        integer :: rtab0 = 0                        !< where its first record starts (64-byte aligned)
        real(dp), allocatable :: dfun(:)            !< several types: density records (rho c3..c6) per knot of each density function
        integer :: dfun0 = 0                        !< where its first record starts (64-byte aligned)
        !> several types, (b, a): column offsets in dfun of the density at a type-a atom from a type-b
        !> atom (doi) and at the type-b atom from the type-a one (doj)
        integer, allocatable :: doi(:, :), doj(:, :)
        !> several types, pairs of two types in the force pass: rho' c0..c2 per knot of each density
        !> function (columns as dfun), z c3..c6 per knot of each r phi function (64-byte aligned),
        !> (b, a): zoff = the column offset of z_ab
        real(dp), allocatable :: ffun(:, :), zfun(:)
        integer :: zfun0 = 0
        integer, allocatable :: zoff(:, :)
        integer, allocatable :: cj(:), cfirst(:)    !< pairs inside the cutoff: partners cj(cfirst(i):cfirst(i+1)-1) of i
        !> several types: the same pairs by segment, those of owned atom i with type-b partners at
        !> cj(cseg(g) : cseg(g+1)-1), g = (i-1)*ntypes + b (the list's rows are ordered by type)
        integer, allocatable :: cseg(:)
        !> several types, lists whose rows are not ordered by type (made by hand): an ordered copy
        integer, allocatable :: oneigh(:), otfirst(:), oscratch(:, :)
        logical :: kept = .false.                   !< cj is the density pass's, for the force pass that follows
        integer :: kept_n = -1, kept_len = -1       !< nlocal and list%first(nlocal+1) it was made with
        character(len=16) :: style = ''
        integer :: nrho = 0, nr = 0                 !< knots of the F tables and of the r tables
        real(dp) :: drho = 0, dr = 0, rdrho = 0, rdr = 0
        real(dp) :: rhomax = 0                      !< F is continued linearly above it
        real(dp) :: rlast = 0                       !< last r knot, (nr - 1) dr
        real(dp) :: cutsq = 0
        real(dp), allocatable :: fspl(:, :, :)      !< F tables (7, nrho, table)
        real(dp), allocatable :: rspl(:, :, :)      !< density tables (7, nr, table)
        real(dp), allocatable :: zspl(:, :, :)      !< r phi tables (7, nr, table)
        integer, allocatable :: t2f(:)              !< F table of a type
        integer, allocatable :: t2rho(:, :)         !< (a, b): density at a type-b atom from a type-a atom
        integer, allocatable :: t2z(:, :)           !< (a, b): r phi table (symmetric)
        logical :: rho_outside = .false.            !< sticky: some owned rho was below 0 or above rhomax
        real(dp) :: rho_low = huge(1.0_dp), rho_high = -huge(1.0_dp)   !< extremes of owned rho seen
        logical :: r_table_short = .false.          !< the r tables end before the cutoff (value held)
        logical :: warned_rho = .false., warned_r = .false.
    contains
        procedure :: read => eam_read
        procedure :: read_funcfl => eam_read_funcfl
        procedure :: density => eam_density
        procedure :: embed => eam_embed
        procedure :: force => eam_force
        procedure :: ray => eam_ray
        procedure :: forces => eam_forces
        procedure :: cutoff => eam_cutoff
        procedure :: describe => eam_describe
        procedure :: needs_full_neighbourhood => eam_needs_full
        procedure :: neighbour_type_order => eam_type_order
        procedure :: contact_distance => eam_contact_distance
        procedure :: warning_flags => eam_warning_flags
        procedure :: embedding => eam_embedding
        procedure :: density_function => eam_density_function
        procedure :: pair_energy => eam_pair_energy
        procedure :: warning => eam_warning_global
        procedure :: warning_local => eam_warning
    end type eam_t

    !> The several-types density pass's sizes and grid (density_types): the owned atoms, the atom
    !> types, the knots of the r tables and 1/dr, the squared cutoff.
    type :: density_pass_t
        integer :: nlocal, ntypes, nr
        real(dp) :: rdr, cutsq
    end type density_pass_t

    interface
        !> src/potentials/eam_simd.c: gather_inside with AVX-512 or AVX2 (-1: neither in this build)
        integer(c_int) function c_gather_inside(xi, yi, zi, x, neigh, nn, cutsq, cj, pp) &
            bind(C, name='terrace_eam_gather_inside')
            import :: c_int, c_double
            real(c_double), value :: xi, yi, zi, cutsq
            real(c_double), intent(in) :: x(*)
            integer(c_int), intent(in) :: neigh(*)
            integer(c_int), value :: nn
            integer(c_int), intent(inout) :: cj(*)
            real(c_double), intent(inout) :: pp(*)
        end function c_gather_inside
    end interface


contains

    ! ------------------------------------------------------------------------------ set-up

    !> Read a potential file. style 'eam' (funcfl: the one file serves every type), 'eam/alloy'
    !> (setfl) or 'eam/fs'; elements(t) names the element of atom type t (setfl/fs; ignored for
    !> funcfl). On failure ok = .false. and msg says what and where ('file:line: ...').
    subroutine eam_read(self, style, path, elements, ntypes, ok, msg)
        class(eam_t), intent(inout) :: self
        character(len=*), intent(in) :: style, path
        character(len=*), intent(in) :: elements(:)
        integer, intent(in) :: ntypes
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        type(eam_file_t) :: file
        character(len=len(path)) :: paths(max(ntypes, 1))
        integer :: t, e, map(max(ntypes, 1))
        ok = .false.
        msg = ''
        self%file_name = path
        if (ntypes < 1) then
            msg = path//': no atom types to map'
            return
        end if
        select case (style)
        case ('eam')
            paths = path
            call self%read_funcfl(paths, ntypes, ok, msg)
            return
        case ('eam/alloy', 'eam/fs')
            call read_setfl_file(path, style == 'eam/fs', file, ok, msg)
            if (.not. ok) return
        case default
            msg = path//': unknown EAM style "'//trim(style)//'" (allowed: eam, eam/alloy, eam/fs)'
            return
        end select
        ok = .false.
        if (size(elements) < ntypes) then
            write (msg, '(a, i0, a, i0, a)') path//': ', ntypes, ' atom types but ', size(elements), &
                ' element names given'
            return
        end if
        do t = 1, ntypes
            map(t) = 0
            do e = 1, file%nelements
                if (trim(adjustl(elements(t))) == trim(file%elements(e))) map(t) = e
            end do
            if (map(t) == 0) then
                write (msg, '(a, i0, a)') path//':4: element "'//trim(adjustl(elements(t)))//'" (atom type ', t, &
                    ') is not in the file (elements: '//joined(file%elements)//')'
                return
            end if
        end do
        call build_setfl(self, file, map(1:ntypes), ntypes)
        self%style = style
        ok = .true.
    end subroutine eam_read

    !> funcfl files, paths(t) for atom type t (the same path may serve several types; it is read
    !> once). The files are resampled onto the common grid described at the top.
    subroutine eam_read_funcfl(self, paths, ntypes, ok, msg)
        class(eam_t), intent(inout) :: self
        character(len=*), intent(in) :: paths(:)
        integer, intent(in) :: ntypes
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        type(eam_file_t), allocatable :: files(:)
        integer :: t, u, nf, map(max(ntypes, 1))
        ok = .false.
        msg = ''
        if (ntypes < 1 .or. size(paths) < ntypes) then
            msg = 'eam: one funcfl file per atom type needed'
            return
        end if
        allocate (files(ntypes))
        nf = 0
        do t = 1, ntypes
            map(t) = 0
            do u = 1, nf
                if (files(u)%path == trim(paths(t))) map(t) = u
            end do
            if (map(t) > 0) cycle
            nf = nf + 1
            call read_funcfl_file(trim(paths(t)), files(nf), ok, msg)
            if (.not. ok) return
            map(t) = nf
        end do
        call build_funcfl(self, files(1:nf), map(1:ntypes), ntypes, ok, msg)
        if (ok) self%style = 'eam'
    end subroutine eam_read_funcfl

    function joined(names) result(s)
        character(len=*), intent(in) :: names(:)
        character(len=:), allocatable :: s
        integer :: k
        s = ''
        do k = 1, size(names)
            s = s//trim(names(k))
            if (k < size(names)) s = s//' '
        end do
    end function joined

    !> Common grid, resampled tables and type maps for funcfl files (files(f), type t uses map(t)).
    subroutine build_funcfl(self, files, map, ntypes, ok, msg)
        type(eam_t), intent(inout) :: self
        type(eam_file_t), intent(in) :: files(:)
        integer, intent(in) :: map(:), ntypes
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        integer :: nf, f, g, m, t, u, npairs
        real(dp) :: rmax, rhomax, x
        real(dp), allocatable :: y(:), zf(:, :), pairz(:)
        integer, allocatable :: pair_of(:, :)
        nf = size(files)
        self%dr = 0; self%drho = 0; rmax = 0; rhomax = 0
        do f = 1, nf
            self%dr = max(self%dr, files(f)%dr)
            self%drho = max(self%drho, files(f)%drho)
            rmax = max(rmax, (files(f)%nr - 1)*files(f)%dr)
            rhomax = max(rhomax, (files(f)%nrho - 1)*files(f)%drho)
        end do
        self%nr = int(rmax/self%dr + 0.5_dp)
        self%nrho = int(rhomax/self%drho + 0.5_dp)
        if (self%nr < 5 .or. self%nrho < 5) then
            ok = .false.
            write (msg, '(a, i0, a, i0, a)') files(1)%path//': the funcfl files give a common grid of ', self%nrho, &
                ' rho and ', self%nr, ' r points (at least 5 needed)'
            return
        end if
        call set_grid(self, ntypes)
        self%rhomax = rhomax
        self%cutmax = maxval(files(:)%cut)
        self%cutsq = self%cutmax**2
        self%r_table_short = self%cutmax > self%rlast
        ! F and rho tables, one per file
        allocate (self%fspl(7, self%nrho, nf), self%rspl(7, self%nr, nf), y(max(self%nrho, self%nr)), &
                  zf(self%nr, nf))
        do f = 1, nf
            do m = 1, self%nrho
                x = (m - 1)*self%drho
                y(m) = lagrange4(files(f)%frho(:, 1), files(f)%drho, x)
            end do
            call build_spline(y(1:self%nrho), self%drho, self%fspl(:, :, f))
            do m = 1, self%nr
                x = (m - 1)*self%dr
                y(m) = lagrange4(files(f)%rhor(:, 1, 1), files(f)%dr, x)
                zf(m, f) = lagrange4(files(f)%zr, files(f)%dr, x)
            end do
            call build_spline(y(1:self%nr), self%dr, self%rspl(:, :, f))
        end do
        ! r phi tables, one per unordered pair of files
        npairs = nf*(nf + 1)/2
        allocate (self%zspl(7, self%nr, npairs), pair_of(nf, nf), pairz(self%nr))
        u = 0
        do f = 1, nf
            do g = 1, f
                u = u + 1
                pair_of(f, g) = u; pair_of(g, f) = u
                pairz = funcfl_z2r_factor*zf(:, f)*zf(:, g)
                call build_spline(pairz, self%dr, self%zspl(:, :, u))
            end do
        end do
        do t = 1, ntypes
            self%t2f(t) = map(t)
            self%mass(t) = files(map(t))%mass(1)
            do u = 1, ntypes
                self%t2rho(t, u) = map(t)
                self%t2z(t, u) = pair_of(map(t), map(u))
            end do
        end do
        ok = .true.
        msg = ''
    end subroutine build_funcfl

    !> Tables and type maps for a setfl/fs file (type t is element map(t)).
    subroutine build_setfl(self, file, map, ntypes)
        type(eam_t), intent(inout) :: self
        type(eam_file_t), intent(in) :: file
        integer, intent(in) :: map(:), ntypes
        integer :: n, i, j, k, t, u
        n = file%nelements
        self%nr = file%nr; self%nrho = file%nrho
        self%dr = file%dr; self%drho = file%drho
        call set_grid(self, ntypes)
        self%rhomax = (self%nrho - 1)*self%drho
        self%cutmax = file%cut
        self%cutsq = self%cutmax**2
        self%r_table_short = self%cutmax > self%rlast
        allocate (self%fspl(7, self%nrho, n), self%rspl(7, self%nr, size(file%rhor, 2)*n), &
                  self%zspl(7, self%nr, n*(n + 1)/2))
        do i = 1, n
            call build_spline(file%frho(:, i), self%drho, self%fspl(:, :, i))
            do k = 1, size(file%rhor, 2)
                call build_spline(file%rhor(:, k, i), self%dr, self%rspl(:, :, k + (i - 1)*size(file%rhor, 2)))
            end do
            do j = 1, i
                call build_spline(file%z2r(:, i, j), self%dr, self%zspl(:, :, pair_index(i, j)))
            end do
        end do
        do t = 1, ntypes
            self%t2f(t) = map(t)
            self%mass(t) = file%mass(map(t))
            do u = 1, ntypes
                if (file%fs) then
                    ! the density a type-t atom puts at a type-u atom: in the section of t's element,
                    ! the function listed in the place of u's element
                    self%t2rho(t, u) = map(u) + (map(t) - 1)*n
                else
                    self%t2rho(t, u) = map(t)
                end if
                self%t2z(t, u) = pair_index(max(map(t), map(u)), min(map(t), map(u)))
            end do
        end do
    contains
        pure integer function pair_index(a, b)
            integer, intent(in) :: a, b        ! a >= b
            pair_index = a*(a - 1)/2 + b
        end function pair_index
    end subroutine build_setfl

    subroutine set_grid(self, ntypes)
        type(eam_t), intent(inout) :: self
        integer, intent(in) :: ntypes
        self%ntypes = ntypes
        self%rdr = 1/self%dr
        self%rdrho = 1/self%drho
        self%rlast = (self%nr - 1)*self%dr
        if (allocated(self%fspl)) deallocate (self%fspl, self%rspl, self%zspl)
        if (allocated(self%t2f)) deallocate (self%t2f, self%t2rho, self%t2z)
        if (allocated(self%mass)) deallocate (self%mass)
        if (allocated(self%ztab)) deallocate (self%ztab)
        if (allocated(self%rtab)) deallocate (self%rtab)
        if (allocated(self%dfun)) deallocate (self%dfun, self%ffun, self%zfun, self%doi, self%doj, self%zoff)
        self%kept = .false.
        allocate (self%t2f(ntypes), self%t2rho(ntypes, ntypes), self%t2z(ntypes, ntypes), self%mass(ntypes))
        self%rho_outside = .false.
        self%rho_low = huge(1.0_dp); self%rho_high = -huge(1.0_dp)
        self%warned_rho = .false.; self%warned_r = .false.
        self%r_table_short = .false.
    end subroutine set_grid

    !> 4-point Lagrange interpolation of the knots y (spacing h, first at 0) at x: through the
    !> knots k-1..k+2 with k = int(x/h + 1) clamped to 2..n-2, offset p = x/h + 1 - k <= 2.
    pure real(dp) function lagrange4(y, h, x) result(v)
        real(dp), intent(in) :: y(:), h, x
        real(dp) :: p, c1, c2, c3, c4
        integer :: k, n
        n = size(y)
        p = x/h + 1
        k = int(min(p, real(n, dp)))
        k = max(2, min(k, n - 2))
        p = min(p - k, 2.0_dp)
        c1 = -p*(p - 1)*(p - 2)/6
        c2 = (p*p - 1)*(p - 2)/2
        c3 = -p*(p + 1)*(p - 2)/2
        c4 = p*(p*p - 1)/6
        v = c1*y(k - 1) + c2*y(k) + c3*y(k + 1) + c4*y(k + 2)
    end function lagrange4

    !> Cubic pieces through the knots y (spacing h), layout s(1:7, m) as described at the top.
    pure subroutine build_spline(y, h, s)
        real(dp), intent(in) :: y(:), h
        real(dp), intent(out) :: s(:, :)
        integer :: n, m
        real(dp) :: dy
        n = size(y)
        s(7, 1:n) = y
        s(6, 1) = y(2) - y(1)
        s(6, 2) = 0.5_dp*(y(3) - y(1))
        s(6, n - 1) = 0.5_dp*(y(n) - y(n - 2))
        s(6, n) = y(n) - y(n - 1)
        do m = 3, n - 2
            s(6, m) = ((y(m - 2) - y(m + 2)) + 8*(y(m + 1) - y(m - 1)))/12
        end do
        do m = 1, n - 1
            dy = y(m + 1) - y(m)
            s(5, m) = 3*dy - 2*s(6, m) - s(6, m + 1)
            s(4, m) = s(6, m) + s(6, m + 1) - 2*dy
        end do
        s(4:5, n) = 0
        s(3, 1:n) = s(6, 1:n)/h
        s(2, 1:n) = 2*s(5, 1:n)/h
        s(1, 1:n) = 3*s(4, 1:n)/h
    end subroutine build_spline

    ! ------------------------------------------------------------------ single evaluations

    !> F(rho) and F'(rho) of type t (as `embed` computes them, linear continuation included).
    pure subroutine eam_embedding(self, t, rho, f, df)
        class(eam_t), intent(in) :: self
        integer, intent(in) :: t
        real(dp), intent(in) :: rho
        real(dp), intent(out) :: f, df
        real(dp) :: p
        integer :: m, k
        k = self%t2f(t)
        p = rho*self%rdrho + 1
        m = int(max(1.0_dp, min(p, real(self%nrho - 1, dp))))
        p = min(p - m, 1.0_dp)
        df = (self%fspl(1, m, k)*p + self%fspl(2, m, k))*p + self%fspl(3, m, k)
        f = ((self%fspl(4, m, k)*p + self%fspl(5, m, k))*p + self%fspl(6, m, k))*p + self%fspl(7, m, k)
        if (rho > self%rhomax) f = f + df*(rho - self%rhomax)
    end subroutine eam_embedding

    !> Density at a type-b atom due to a type-a atom at distance r (0 at and beyond the cutoff).
    pure real(dp) function eam_density_function(self, a, b, r) result(v)
        class(eam_t), intent(in) :: self
        integer, intent(in) :: a, b
        real(dp), intent(in) :: r
        v = r_table_value(self, self%rspl, self%t2rho(a, b), r)
    end function eam_density_function

    !> Pair energy phi_ab(r) (0 at and beyond the cutoff).
    pure real(dp) function eam_pair_energy(self, a, b, r) result(v)
        class(eam_t), intent(in) :: self
        integer, intent(in) :: a, b
        real(dp), intent(in) :: r
        v = r_table_value(self, self%zspl, self%t2z(a, b), r)/r
    end function eam_pair_energy

    !> Value at distance r of the cubic spline k of an r-table (rspl or zspl); 0 at and beyond the
    !> cutoff.
    pure real(dp) function r_table_value(self, spl, k, r) result(v)
        class(eam_t), intent(in) :: self
        real(dp), intent(in) :: spl(:, :, :)
        integer, intent(in) :: k
        real(dp), intent(in) :: r
        real(dp) :: p
        integer :: m
        v = 0
        if (r*r >= self%cutsq) return
        p = r*self%rdr + 1
        m = int(min(p, real(self%nr - 1, dp)))
        p = min(p - m, 1.0_dp)
        v = ((spl(4, m, k)*p + spl(5, m, k))*p + spl(6, m, k))*p + spl(7, m, k)
    end function r_table_value

    !> A message, once per kind of event, when the tables were left: rho outside [0, rhomax] (F
    !> continued) or a cutoff beyond the last r knot. Returns .false. when there is nothing new.
    !> (Per rank: in parallel, reduce rho_outside / rho_low / rho_high first.)
    logical function eam_warning(self, text) result(have)
        class(eam_t), intent(inout) :: self
        character(len=*), intent(out) :: text
        character(len=24) :: a, b, c
        have = .false.
        text = ''
        if (self%r_table_short .and. .not. self%warned_r) then
            self%warned_r = .true.
            write (a, '(es12.5)') self%cutmax
            write (b, '(es12.5)') self%rlast
            text = 'eam: the cutoff '//trim(adjustl(a))//' lies beyond the last r knot '//trim(adjustl(b))// &
                   ' of the tables; values there are held at the last knot (as LAMMPS does)'
            have = .true.
            return
        end if
        if (self%rho_outside .and. .not. self%warned_rho) then
            self%warned_rho = .true.
            write (a, '(es12.5)') self%rho_low
            write (b, '(es12.5)') self%rho_high
            write (c, '(es12.5)') self%rhomax
            text = 'eam: electron densities from '//trim(adjustl(a))//' to '//trim(adjustl(b))// &
                   ' left the F(rho) table [0, '//trim(adjustl(c))//']; F continued as LAMMPS does (linearly '// &
                   'above rhomax, the first cubic piece below 0)'
            have = .true.
        end if
    end function eam_warning

    ! ---------------------------------------------------------------- the potential interface

    pure real(dp) function eam_cutoff(self)
        class(eam_t), intent(in) :: self
        eam_cutoff = self%cutmax
    end function eam_cutoff

    function eam_describe(self) result(text)
        class(eam_t), intent(in) :: self
        character(len=:), allocatable :: text
        text = trim(self%style)//' from '//self%file_name//'; density pass, reverse sum of rho and forward halo of F''(rho)'
    end function eam_describe

    !> The ray pass completes every owned atom's density locally (list%below); the force pass
    !> reverse-sums instead.
    pure logical function eam_needs_full(self, energy_stepping)
        class(eam_t), intent(in) :: self
        logical, intent(in) :: energy_stepping
        eam_needs_full = energy_stepping
    end function eam_needs_full

    !> Several types: the passes take the list's rows ordered by type (one table choice per segment
    !> of an atom's row instead of a type lookup per neighbour).
    pure integer function eam_type_order(self)
        class(eam_t), intent(in) :: self
        eam_type_order = merge(self%ntypes, 0, self%ntypes > 1)
    end function eam_type_order

    !> A contact distance for the overlap check: about the nearest-neighbour distance.
    pure real(dp) function eam_contact_distance(self, ti, tj)
        class(eam_t), intent(in) :: self
        integer, intent(in) :: ti, tj
        eam_contact_distance = 0.4_dp*self%cutmax
    end function eam_contact_distance

    pure function eam_warning_flags(self) result(flags)
        class(eam_t), intent(in) :: self
        logical :: flags(max_warning_flags)
        flags = .false.
        flags(1) = self%rho_outside
        flags(2) = self%r_table_short
    end function eam_warning_flags

    !> This rank's own warning if it has one, else a general one when another rank had one.
    logical function eam_warning_global(self, global_flags, text) result(have)
        class(eam_t), intent(inout) :: self
        logical, intent(in) :: global_flags(max_warning_flags)
        character(len=*), intent(out) :: text
        have = self%warning_local(text)
        if (.not. have .and. any(global_flags(1:2))) then
            text = 'eam: some ranks left the tabulated range of the potential (densities or distances); '// &
                   'values were continued as LAMMPS does'
            have = .true.
        end if
    end function eam_warning_global

    ! ----------------------------------------------------------------------------- kernels

    include 'eam_force.inc'
    include 'eam_ray.inc'

end module terrace_eam
