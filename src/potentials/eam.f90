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

    interface
        !> src/potentials/eam_simd.c: gather_inside with AVX-512 (-1: not in this build)
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

    !> Density pass over the half list, reverse sum of the ghost densities into their owners,
    !> F'(rho) of the owned atoms, forward copy of F'(rho) to the ghosts, force pass. energy = pair +
    !> embedding energy of this rank (when want_energy), virial of its pairs.
    subroutine eam_forces(self, atoms, list, halo, want_energy, energy, virial)
        class(eam_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        type(neighbor_list_t), intent(in) :: list
        class(halo_ops_t), intent(inout) :: halo
        logical, intent(in) :: want_energy
        real(dp), intent(out) :: energy, virial
        integer :: nall
        real(dp) :: e_embed, e_pair
        nall = atoms%nall()
        call self%density(atoms, list)
        if (allocated(self%halo_buf)) then
            if (size(self%halo_buf, 2) < nall) deallocate (self%halo_buf)
        end if
        if (.not. allocated(self%halo_buf)) allocate (self%halo_buf(1, nall + nall/4 + 16))
        self%halo_buf(1, 1:nall) = self%rho(1:nall)
        call halo%reverse_sum(self%halo_buf(:, 1:nall))
        self%rho(1:atoms%nlocal) = self%halo_buf(1, 1:atoms%nlocal)
        call self%embed(atoms, want_energy, e_embed)
        self%halo_buf(1, 1:nall) = self%fp(1:nall)
        call halo%forward(self%halo_buf(:, 1:nall))
        self%fp(1:nall) = self%halo_buf(1, 1:nall)
        call self%force(atoms, list, want_energy, e_pair, virial)
        energy = 0
        if (want_energy) energy = e_embed + e_pair
    end subroutine eam_forces

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

    !> rho(1:nall) = 0, then over the half list: rho_i += rho_ba(r), rho_j += rho_ab(r) (ghosts
    !> included; the caller reverse-sums ghost values into their owners).
    subroutine eam_density(self, atoms, list)
        class(eam_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        type(neighbor_list_t), intent(in) :: list
        integer :: nall
        nall = atoms%nlocal + atoms%nghost
        call reserve(self%rho, nall, minimum=64, zero=.true.)
        call reserve(self%fp, nall, minimum=64, zero=.true.)
        self%rho(1:nall) = 0
        self%kept = .false.
        if (atoms%nlocal == 0) return
        call reserve_work(self, atoms%nlocal, list%first)
        call reserve_pairs(self, atoms%nlocal, list%first)
        if (self%ntypes == 1) then
            if (.not. allocated(self%rtab)) call build_rtab(self)
            call density_one(atoms%nlocal, atoms%x, list%first, list%neigh, self%cutsq, self%rdr, self%nr, &
                             self%rtab(self%rtab0 + 1:), self%rho, self%cj, self%cfirst, self%work(:, 1), &
                             self%iwork(:, 1))
        else
            if (.not. allocated(self%dfun)) call build_pair_tables(self)
            if (list%type_order == self%ntypes) then
                call density_several(self, atoms, list%neigh, list%tfirst)
            else
                call ordered_copy(self, list, atoms%type, atoms%nlocal)
                call density_several(self, atoms, self%oneigh, self%otfirst)
            end if
        end if
        self%kept = .true.
        self%kept_n = atoms%nlocal
        self%kept_len = list%first(atoms%nlocal + 1)
    end subroutine eam_density

    !> The several-types density pass over rows ordered by type: neigh, tfirst as list%neigh,
    !> list%tfirst (the list's or ordered_copy's).
    subroutine density_several(self, atoms, neigh, tfirst)
        type(eam_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        integer, intent(in), contiguous :: neigh(:), tfirst(:)
        call density_types(atoms%nlocal, self%ntypes, atoms%x, atoms%type, tfirst, neigh, self%cutsq, self%rdr, &
                           self%nr, self%doi, self%doj, self%dfun(self%dfun0 + 1:), &
                           self%rho, self%cj, self%cfirst, self%cseg, self%work(:, 1), self%iwork(:, 1))
    end subroutine density_several

    !> The several-types pairs inside the cutoff by segment (cj, cseg), and cfirst from them, for a
    !> force pass not preceded by a density pass; neigh, tfirst as in density_several.
    subroutine segments_several(self, atoms, neigh, tfirst)
        type(eam_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        integer, intent(in), contiguous :: neigh(:), tfirst(:)
        integer :: i
        call inside_pairs(atoms%nlocal, self%ntypes, atoms%x, tfirst, neigh, self%cutsq, self%cj, self%cseg, &
                          self%work(:, 1), self%work(:, 2), self%work(:, 3), self%work(:, 4))
        do i = 1, atoms%nlocal + 1
            self%cfirst(i) = self%cseg((i - 1)*self%ntypes + 1)
        end do
    end subroutine segments_several

    !> A copy of the list's rows ordered by type (oneigh, otfirst as list%neigh, list%tfirst), for
    !> lists built without type_order.
    subroutine ordered_copy(self, list, type, nlocal)
        type(eam_t), intent(inout) :: self
        type(neighbor_list_t), intent(in) :: list
        integer, intent(in) :: type(:), nlocal
        integer :: n, nb
        n = list%first(nlocal + 1) - 1
        nb = max(longest_row(list%first, nlocal), 1)
        call reserve(self%oneigh, max(n, 1))
        call reserve(self%otfirst, self%ntypes*nlocal + 1)
        if (allocated(self%oscratch)) then
            if (size(self%oscratch, 1) < nb + 1) deallocate (self%oscratch)
        end if
        if (.not. allocated(self%oscratch)) allocate (self%oscratch(nb + 1, 3))
        self%oneigh(1:n) = list%neigh(1:n)
        call order_rows_by_type(list%first, self%oneigh, type, nlocal, self%ntypes, self%otfirst, self%oscratch)
    end subroutine ordered_copy

    !> fp(1:nlocal) = F'(rho); energy = sum of F(rho_i) over owned atoms when want_energy (else 0).
    subroutine eam_embed(self, atoms, want_energy, energy)
        class(eam_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        logical, intent(in) :: want_energy
        real(dp), intent(out) :: energy
        integer :: n
        real(dp) :: lo, hi
        n = atoms%nlocal
        energy = 0
        call reserve(self%fp, atoms%nlocal + atoms%nghost, minimum=64, zero=.true.)
        if (n == 0) return
        call embed_kernel(n, atoms%type, self%t2f, self%fspl, self%rdrho, self%nrho, self%rhomax, self%rho, &
                          want_energy, self%fp, energy, lo, hi)
        self%rho_low = min(self%rho_low, lo)
        self%rho_high = max(self%rho_high, hi)
        if (lo < 0 .or. hi > self%rhomax) self%rho_outside = .true.
    end subroutine eam_embed

    !> Pair and embedding forces added to atoms%f (owned and ghost) over the half list, with fp of
    !> owned and ghost atoms (the caller has forwarded fp to the ghosts). When want_energy: energy =
    !> sum of phi over the pairs held, virial = sum over them of d.F_i (else both 0). Right after
    !> `density` (same positions and list, as in `forces`) it takes the pairs inside the cutoff
    !> that the density pass found; otherwise it finds them first.
    subroutine eam_force(self, atoms, list, want_energy, energy, virial)
        class(eam_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        type(neighbor_list_t), intent(in) :: list
        logical, intent(in) :: want_energy
        real(dp), intent(out) :: energy, virial
        energy = 0; virial = 0
        if (atoms%nlocal == 0) then
            self%kept = .false.
            return
        end if
        call reserve_work(self, atoms%nlocal, list%first)
        if (self%ntypes > 1 .and. .not. allocated(self%dfun)) call build_pair_tables(self)
        if (.not. (self%kept .and. self%kept_n == atoms%nlocal .and. self%kept_len == list%first(atoms%nlocal + 1))) then
            call reserve_pairs(self, atoms%nlocal, list%first)
            if (self%ntypes == 1) then
                call inside_pairs(atoms%nlocal, 1, atoms%x, list%first, list%neigh, self%cutsq, self%cj, self%cfirst, &
                                  self%work(:, 1), self%work(:, 2), self%work(:, 3), self%work(:, 4))
            else if (list%type_order == self%ntypes) then
                call segments_several(self, atoms, list%neigh, list%tfirst)
            else
                call ordered_copy(self, list, atoms%type, atoms%nlocal)
                call segments_several(self, atoms, self%oneigh, self%otfirst)
            end if
        end if
        self%kept = .false.
        if (self%ntypes == 1) then
            if (.not. allocated(self%ztab)) call build_ztab(self)
            call force_one(atoms%nlocal, atoms%x, atoms%f, self%cj, self%cfirst, self%rdr, self%nr, &
                           self%ztab, self%fp, want_energy, energy, virial, self%work(:, 1), self%work(:, 2), &
                           self%work(:, 3), self%work(:, 4), self%work(:, 5), self%work(:, 6), self%work(:, 7), &
                           self%work(:, 8), self%iwork(:, 2))
        else
            call force_types(atoms%nlocal, self%ntypes, atoms%x, atoms%f, atoms%type, self%cj, self%cfirst, &
                             self%cseg, self%rdr, self%nr, self%doi, self%doj, self%zoff, self%ffun, &
                             self%zfun(self%zfun0 + 1:), self%fp, want_energy, energy, virial, &
                             self%work(:, 1), self%work(:, 2), self%work(:, 3), self%work(:, 4), self%work(:, 5), &
                             self%work(:, 6), self%work(:, 7), self%work(:, 8), self%iwork(:, 2))
        end if
    end subroutine eam_force

    !> Energy stepping's ray pass: out = (V, dV/ds, d2V/ds2, W) along x + s v (every atom, ghosts
    !> included, moves with its own velocity): this rank's share; the caller sums over ranks (the
    !> only communication). Needs the list built with want_below.
    !>
    !> Design (no reverse sum): V = sum_pairs phi + sum_owned F(rho_i). The pair part runs over the
    !> half list (each pair once across ranks). The embedding part needs rho_i, rho_i', rho_i'' of
    !> every owned atom complete on this rank. Ghosts exist within cutoff + skin of the subdomain,
    !> so every owned atom's whole neighbourhood is here: the half list's owned-owned pairs add to
    !> both atoms, its owned-ghost pairs to the owned atom only, and list%below (the ghosts the half
    !> list leaves to their owners) completes the neighbourhood of each owned atom. Ghost
    !> densities are never formed; each pair's density terms are thus evaluated once per owning
    !> rank of each end (twice for pairs across ranks), the pair energy once. Along the ray, with
    !> d = x_i - x_j and w = v_i - v_j at s, r' = d.w/r, r'' = (|w|^2 - r'^2)/r:
    !>   rho_i' = sum_j f'(r) r',   rho_i'' = sum_j f''(r) r'^2 + f'(r) r'',
    !>   V' += F'(rho_i) rho_i' + phi'(r) r',   V'' += F''(rho_i) rho_i'^2 + F'(rho_i) rho_i'' + phi'' r'^2 + phi' r''.
    !> The virial -sum_pairs r psi'(r) splits into -sum_pairs r phi'(r) - sum_owned F'(rho_i) sum_j r f_ji'(r),
    !> the inner sum gathered per owned atom like rho. Derivatives of the interpolants are those of
    !> the cubic pieces (y'' = (2 c0 p + c1)/h); where F is continued (rho beyond the table) F' is
    !> the held slope of the force pass and F'' = 0.
    subroutine eam_ray(self, atoms, list, s, out)
        class(eam_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        type(neighbor_list_t), intent(in) :: list
        real(dp), intent(in) :: s
        real(dp), intent(out) :: out(4)
        integer :: n
        real(dp) :: lo, hi
        n = atoms%nlocal
        out = 0
        if (n == 0) return
        if (allocated(self%ray_acc)) then
            if (size(self%ray_acc, 2) < n) deallocate (self%ray_acc)
        end if
        if (.not. allocated(self%ray_acc)) allocate (self%ray_acc(4, n + n/4 + 16))
        call reserve_work(self, n, list%first)
        call reserve_work(self, n, list%below_first)
        if (self%ntypes == 1) then    ! (tfirst not read: the rows' first stands in)
            call ray_staged(self, n, atoms%x, atoms%v, atoms%type, list%first, list%neigh, list%first, &
                            list%below_first, list%below, s, self%ray_acc, out)
        else if (list%type_order == self%ntypes) then
            call ray_staged(self, n, atoms%x, atoms%v, atoms%type, list%first, list%neigh, list%tfirst, &
                            list%below_first, list%below, s, self%ray_acc, out)
        else
            call ordered_copy(self, list, atoms%type, n)
            call ray_staged(self, n, atoms%x, atoms%v, atoms%type, list%first, self%oneigh, self%otfirst, &
                            list%below_first, list%below, s, self%ray_acc, out)
        end if
        call ray_embed(n, atoms%type, self%t2f, self%fspl, self%rdrho, self%nrho, self%rhomax, self%ray_acc, out, lo, hi)
        self%rho_low = min(self%rho_low, lo)
        self%rho_high = max(self%rho_high, hi)
        if (lo < 0 .or. hi > self%rhomax) self%rho_outside = .true.
    end subroutine eam_ray

    !> Pair terms of the ray (half list) and the per-atom density sums acc(1:4, i) = (rho, rho',
    !> rho'', sum_j r f') of owned atoms (half list + below list), staged like force_one: per atom,
    !> each pair's |d|^2, d.w and |w|^2 (separation d, relative velocity w at s) gathered into rows,
    !> the pairs inside the cutoff compacted without branches, r, 1/r, r', r'', knot and offset
    !> vectorised, then the lookups. One type: the tables are fixed for the pass. Several types: the
    !> half list's rows are ordered by type (tfirst, as list%tfirst), so the tables (t2z, t2rho) are
    !> fixed per segment (the ray pass of the CuNi alloy an eighth cheaper than with each pair's
    !> types read in the lookup loop, phase_ab.sh); the complement's pairs read their neighbour's
    !> type.
    subroutine ray_staged(self, nlocal, x, v, type, first, neigh, tfirst, bfirst, below, s, acc, out)
        type(eam_t), intent(inout) :: self
        integer, intent(in) :: nlocal
        real(dp), intent(in), contiguous :: x(:, :), v(:, :)
        integer, intent(in), contiguous :: type(:), first(:), neigh(:), bfirst(:), below(:)
        integer, intent(in) :: tfirst(*)   ! several types: the rows' segments by type (list%tfirst)
        real(dp), intent(in) :: s
        real(dp), intent(inout), contiguous :: acc(:, :)
        real(dp), intent(inout) :: out(4)
        integer :: i, j, k, m, nin, a, b, c, ti, tj, bi, bj, g, k1, k2, lim
        real(dp) :: xi, yi, zi, vxi, vyi, vzi, p, top, cutsq, rdr, r, rinv, rp, z, zp, zpp, phi, phip, phipp, &
                    f0, f1, f2, e, e1, e2, w, a1, a2, a3, a4, q1, q2, ei, ce
        logical :: one
        top = self%nr - 1; cutsq = self%cutsq; rdr = self%rdr
        one = self%ntypes == 1
        a = self%t2rho(1, 1); c = self%t2z(1, 1)
        e = 0; e1 = 0; e2 = 0; w = 0; ce = 0
        acc(:, 1:nlocal) = 0
        associate (sr => self%rspl(:, :, a), sz => self%zspl(:, :, c), rs => self%rspl, zs => self%zspl, &
                   rr => self%work(:, 7), pp => self%work(:, 8), rpv => self%work(:, 9), rppv => self%work(:, 10), &
                   rv => self%work(:, 11), kk => self%iwork(:, 1), mm => self%iwork(:, 2))
        do i = 1, nlocal
            vxi = v(1, i); vyi = v(2, i); vzi = v(3, i)
            xi = x(1, i) + s*vxi; yi = x(2, i) + s*vyi; zi = x(3, i) + s*vzi
            ti = type(i)
            a1 = 0; a2 = 0; a3 = 0; a4 = 0; ei = 0
            ! the half list (pair terms; densities of i and of owned j), then the complement (density of i)
            call stage(neigh, first(i) - 1, first(i + 1) - first(i))
            ! (two versions of each lookup loop: one loop with the per-pair tables behind tests on
            ! `one` and the density terms in a procedure made the ray pass 25 % slower on 108 Cu atoms
            ! and 18 % on the CuNi alloy, phase_ab.sh)
            if (one) then
                do k = 1, nin
                    m = mm(k); p = pp(k); r = rv(k); rinv = rr(k); rp = rpv(k)
                    z = ((sz(4, m)*p + sz(5, m))*p + sz(6, m))*p + sz(7, m)
                    zp = (sz(1, m)*p + sz(2, m))*p + sz(3, m)
                    zpp = (2*sz(1, m)*p + sz(2, m))*rdr
                    phi = z*rinv
                    phip = (zp - phi)*rinv
                    phipp = (zpp - 2*phip)*rinv
                    ei = ei + phi; e1 = e1 + phip*rp; e2 = e2 + phipp*rp*rp + phip*rppv(k); w = w - r*phip
                    f0 = ((sr(4, m)*p + sr(5, m))*p + sr(6, m))*p + sr(7, m)
                    f1 = (sr(1, m)*p + sr(2, m))*p + sr(3, m)
                    f2 = (2*sr(1, m)*p + sr(2, m))*rdr
                    q1 = f1*rp
                    q2 = f2*rp*rp + f1*rppv(k)
                    a1 = a1 + f0; a2 = a2 + q1; a3 = a3 + q2; a4 = a4 + r*f1
                    j = neigh(first(i) - 1 + kk(k))
                    if (j <= nlocal) then
                        acc(1, j) = acc(1, j) + f0; acc(2, j) = acc(2, j) + q1
                        acc(3, j) = acc(3, j) + q2; acc(4, j) = acc(4, j) + r*f1
                    end if
                end do
            else
                ! segment by segment of the row ordered by type (the staged pairs keep the list's
                ! order: those of segment tj are the next ones up to its end): tables fixed per segment
                g = (i - 1)*self%ntypes
                k2 = 0
                do tj = 1, self%ntypes
                    k1 = k2 + 1
                    lim = tfirst(g + tj + 1) - first(i)
                    do k = k1, nin
                        k2 = k2 + merge(1, 0, kk(k) <= lim)
                    end do
                    c = self%t2z(ti, tj)
                    bi = self%t2rho(tj, ti)     ! density at i from j
                    bj = self%t2rho(ti, tj)     ! density at j from i
                    do k = k1, k2
                        j = neigh(first(i) - 1 + kk(k))
                        m = mm(k); p = pp(k); r = rv(k); rinv = rr(k); rp = rpv(k)
                        z = ((zs(4, m, c)*p + zs(5, m, c))*p + zs(6, m, c))*p + zs(7, m, c)
                        zp = (zs(1, m, c)*p + zs(2, m, c))*p + zs(3, m, c)
                        zpp = (2*zs(1, m, c)*p + zs(2, m, c))*rdr
                        phi = z*rinv
                        phip = (zp - phi)*rinv
                        phipp = (zpp - 2*phip)*rinv
                        ei = ei + phi; e1 = e1 + phip*rp; e2 = e2 + phipp*rp*rp + phip*rppv(k); w = w - r*phip
                        f0 = ((rs(4, m, bi)*p + rs(5, m, bi))*p + rs(6, m, bi))*p + rs(7, m, bi)
                        f1 = (rs(1, m, bi)*p + rs(2, m, bi))*p + rs(3, m, bi)
                        f2 = (2*rs(1, m, bi)*p + rs(2, m, bi))*rdr
                        a1 = a1 + f0; a2 = a2 + f1*rp; a3 = a3 + (f2*rp*rp + f1*rppv(k)); a4 = a4 + r*f1
                        if (j <= nlocal) then
                            f0 = ((rs(4, m, bj)*p + rs(5, m, bj))*p + rs(6, m, bj))*p + rs(7, m, bj)
                            f1 = (rs(1, m, bj)*p + rs(2, m, bj))*p + rs(3, m, bj)
                            f2 = (2*rs(1, m, bj)*p + rs(2, m, bj))*rdr
                            acc(1, j) = acc(1, j) + f0; acc(2, j) = acc(2, j) + f1*rp
                            acc(3, j) = acc(3, j) + (f2*rp*rp + f1*rppv(k)); acc(4, j) = acc(4, j) + r*f1
                        end if
                    end do
                end do
            end if
            call stage(below, bfirst(i) - 1, bfirst(i + 1) - bfirst(i))
            if (one) then
                do k = 1, nin
                    m = mm(k); p = pp(k); r = rv(k); rp = rpv(k)
                    f0 = ((sr(4, m)*p + sr(5, m))*p + sr(6, m))*p + sr(7, m)
                    f1 = (sr(1, m)*p + sr(2, m))*p + sr(3, m)
                    f2 = (2*sr(1, m)*p + sr(2, m))*rdr
                    a1 = a1 + f0; a2 = a2 + f1*rp; a3 = a3 + f2*rp*rp + f1*rppv(k); a4 = a4 + r*f1
                end do
            else
                do k = 1, nin
                    b = self%t2rho(type(below(bfirst(i) - 1 + kk(k))), ti)
                    m = mm(k); p = pp(k); r = rv(k); rp = rpv(k)
                    f0 = ((rs(4, m, b)*p + rs(5, m, b))*p + rs(6, m, b))*p + rs(7, m, b)
                    f1 = (rs(1, m, b)*p + rs(2, m, b))*p + rs(3, m, b)
                    f2 = (2*rs(1, m, b)*p + rs(2, m, b))*rdr
                    a1 = a1 + f0; a2 = a2 + f1*rp; a3 = a3 + (f2*rp*rp + f1*rppv(k)); a4 = a4 + r*f1
                end do
            end if
            acc(1, i) = acc(1, i) + a1; acc(2, i) = acc(2, i) + a2
            acc(3, i) = acc(3, i) + a3; acc(4, i) = acc(4, i) + a4
            call comp_add(e, ce, ei)
        end do
        end associate
        out = out + [e + ce, e1, e2, w]
    contains
        !> Rows for the nn neighbours list(k0+1 : k0+nn) of atom i: the nin inside the cutoff, with
        !> r (rv), 1/r (rr), r' (rpv), r'' (rppv), knot (mm), offset (pp) and list position (kk).
        !> The gather forms each pair's |d|^2, d.w and |w|^2 (three rows, not d and w: six rows
        !> stored, compacted and read again cost a fifth more per ray evaluation in the LJ pass).
        subroutine stage(list, k0_, nn_)
            integer, intent(in), contiguous :: list(:)
            integer, intent(in) :: k0_, nn_
            integer :: q, jj, mq
            real(dp) :: ddx, ddy, ddz, dwx, dwy, dwz, rq, rinvq, rpq, pq, rsq_q, dw_q, ww_q
            associate (dw => self%work(:, 1), ww => self%work(:, 2), rr => self%work(:, 7), pp => self%work(:, 8), &
                       rpv => self%work(:, 9), rppv => self%work(:, 10), rv => self%work(:, 11), kk => self%iwork(:, 1), &
                       mm => self%iwork(:, 2))
            !GCC$ novector
            do q = 1, nn_
                jj = list(k0_ + q)
                dwx = vxi - v(1, jj); dwy = vyi - v(2, jj); dwz = vzi - v(3, jj)
                ddx = xi - (x(1, jj) + s*v(1, jj)); ddy = yi - (x(2, jj) + s*v(2, jj))
                ddz = zi - (x(3, jj) + s*v(3, jj))
                rr(q) = ddx*ddx + ddy*ddy + ddz*ddz
                dw(q) = ddx*dwx + ddy*dwy + ddz*dwz
                ww(q) = dwx*dwx + dwy*dwy + dwz*dwz
            end do
            nin = 0
            do q = 1, nn_
                rsq_q = rr(q); dw_q = dw(q); ww_q = ww(q)
                dw(nin + 1) = dw_q; ww(nin + 1) = ww_q
                pp(nin + 1) = rsq_q
                kk(nin + 1) = q
                nin = nin + merge(1, 0, rsq_q < cutsq)
            end do
            do q = 1, nin
                rq = sqrt(pp(q))
                rinvq = 1/rq
                rpq = dw(q)*rinvq
                rv(q) = rq
                rr(q) = rinvq
                rpv(q) = rpq
                rppv(q) = (ww(q) - rpq*rpq)*rinvq
                pq = rq*rdr + 1
                mq = int(min(pq, top))
                mm(q) = mq
                pp(q) = min(pq - mq, 1.0_dp)
            end do
            end associate
        end subroutine stage
    end subroutine ray_staged

    !> Embedding terms of the ray from acc(1:4, i) = (rho, rho', rho'', sum_j r f'): F(rho_i),
    !> F' rho', F'' rho'^2 + F' rho'', and the virial share -F' sum_j r f'; lo, hi: extremes of rho.
    subroutine ray_embed(n, type, t2f, fspl, rdrho, nrho, rhomax, acc, out, lo, hi)
        integer, intent(in) :: n, nrho
        integer, intent(in), contiguous :: type(:), t2f(:)
        real(dp), intent(in), contiguous :: fspl(:, :, :), acc(:, :)
        real(dp), intent(in) :: rdrho, rhomax
        real(dp), intent(inout) :: out(4)
        real(dp), intent(out) :: lo, hi
        integer :: i, m, k
        real(dp) :: p, top, rho, f0, f1, f2, e, e1, e2, w, ce
        top = nrho - 1
        e = 0; e1 = 0; e2 = 0; w = 0; ce = 0
        lo = huge(1.0_dp); hi = -huge(1.0_dp)
        do i = 1, n
            k = t2f(type(i))
            rho = acc(1, i)
            p = rho*rdrho + 1
            m = int(max(1.0_dp, min(p, top)))
            p = p - m
            if (p > 1) then
                ! held end of the table (and linear continuation above rhomax): F'' = 0
                p = 1
                f2 = 0
            else
                f2 = (2*fspl(1, m, k)*p + fspl(2, m, k))*rdrho
            end if
            f1 = (fspl(1, m, k)*p + fspl(2, m, k))*p + fspl(3, m, k)
            f0 = ((fspl(4, m, k)*p + fspl(5, m, k))*p + fspl(6, m, k))*p + fspl(7, m, k)
            if (rho > rhomax) f0 = f0 + f1*(rho - rhomax)
            call comp_add(e, ce, f0)
            e1 = e1 + f1*acc(2, i)
            e2 = e2 + f2*acc(2, i)**2 + f1*acc(3, i)
            w = w - f1*acc(4, i)
            lo = min(lo, rho); hi = max(hi, rho)
        end do
        out = out + [e + ce, e1, e2, w]
    end subroutine ray_embed

    !> Work rows for the one-type kernels: as long as the longest row of the list (counted here from
    !> first(1:nlocal+1), which every list has, hand-built ones included).
    subroutine reserve_work(self, nlocal, first)
        type(eam_t), intent(inout) :: self
        integer, intent(in) :: nlocal
        integer, intent(in), contiguous :: first(:)
        integer :: i, nb
        nb = 0
        do i = 1, nlocal
            nb = max(nb, first(i + 1) - first(i))
        end do
        nb = max(nb + 16, block_pairs)
        if (allocated(self%work)) then
            if (size(self%work, 1) < nb) deallocate (self%work, self%iwork)
        end if
        if (.not. allocated(self%work)) allocate (self%work(nb + nb/4, 12), self%iwork(nb + nb/4, 3))
    end subroutine reserve_work

    !> One type: the density pass's records, rho c3..c6 per knot (32 bytes, the table 64-byte
    !> aligned: a record never straddles a cache line; the rows of rspl are 56 bytes).
    subroutine build_rtab(self)
        type(eam_t), intent(inout) :: self
        integer :: n
        n = 4*self%nr
        allocate (self%rtab(n + 8))
        self%rtab0 = align_shift(self%rtab)
        self%rtab(self%rtab0 + 1:self%rtab0 + n) = reshape(self%rspl(4:7, :, self%t2rho(1, 1)), [n])
    end subroutine build_rtab

    !> One type: the force pass's lookups side by side per knot, so that a pair reads one record:
    !> t(1:3, m) = rho' coefficients (c0, c1, c2), t(4:7, m) = z coefficients (c3, c4, c5, y), as in
    !> rspl / zspl. z' is formed from z's own coefficients, ((3 c3 p + 2 c4) p + c5)/dr (what its
    !> stored c0..c2 are): 56-byte records instead of 80.
    subroutine build_ztab(self)
        type(eam_t), intent(inout) :: self
        integer :: a, c
        a = self%t2rho(1, 1); c = self%t2z(1, 1)
        allocate (self%ztab(7, self%nr))
        self%ztab(1:3, :) = self%rspl(1:3, :, a)
        self%ztab(4:7, :) = self%zspl(4:7, :, c)
    end subroutine build_ztab

    !> Several types: the tables of the density and force passes, one per function of the file (the
    !> passes pick them once per segment of a row ordered by type, so a pair type needs no record of
    !> its own), knots contiguous per function, function f's knot m at column (f-1) nr + m:
    !>   dfun: rho c3..c6 (the one-type density record), 64-byte aligned;
    !>   ffun: rho' c0..c2;
    !>   zfun: z = r phi c3..c6 (z' from them, as in build_ztab), 64-byte aligned;
    !> and per type pair (b, a) the column offsets of the density at the type-a atom from the type-b
    !> one (doi), at the type-b atom from the type-a one (doj), and of z_ab (zoff).
    subroutine build_pair_tables(self)
        type(eam_t), intent(inout) :: self
        integer :: ta, tb, nt, nr, nf, nz
        nt = self%ntypes; nr = self%nr
        nf = size(self%rspl, 3); nz = size(self%zspl, 3)
        allocate (self%dfun(4*nr*nf + 8), self%ffun(3, nr*nf), self%zfun(4*nr*nz + 8))
        allocate (self%doi(nt, nt), self%doj(nt, nt), self%zoff(nt, nt))
        self%dfun0 = align_shift(self%dfun)
        self%zfun0 = align_shift(self%zfun)
        self%dfun(self%dfun0 + 1:self%dfun0 + 4*nr*nf) = reshape(self%rspl(4:7, :, :), [4*nr*nf])
        self%ffun = reshape(self%rspl(1:3, :, :), [3, nr*nf])
        self%zfun(self%zfun0 + 1:self%zfun0 + 4*nr*nz) = reshape(self%zspl(4:7, :, :), [4*nr*nz])
        do ta = 1, nt
            do tb = 1, nt
                self%doi(tb, ta) = (self%t2rho(tb, ta) - 1)*nr
                self%doj(tb, ta) = (self%t2rho(ta, tb) - 1)*nr
                self%zoff(tb, ta) = (self%t2z(ta, tb) - 1)*nr
            end do
        end do
    end subroutine build_pair_tables

    !> Elements to skip from the start of a so that the rest starts on a 64-byte boundary (0..7).
    integer function align_shift(a) result(k)
        real(dp), intent(in), target :: a(:)
        integer(c_intptr_t) :: addr
        addr = transfer(c_loc(a(1)), addr)
        k = int(modulo(-addr, 64_c_intptr_t)/8)
    end function align_shift


    !> Separations (dx, dy, dz)(k) = x_i - x_j and their squares rr(k) for the nn neighbours
    !> j = neigh(k0 + k) of an atom at (xi, yi, zi): a scalar gather into contiguous rows, then a
    !> vectorised pass (for inside_pairs).
    subroutine separations(xi, yi, zi, x, neigh, k0, nn, dx, dy, dz, rr)
        real(dp), intent(in) :: xi, yi, zi
        real(dp), intent(in), contiguous :: x(:, :)
        integer, intent(in), contiguous :: neigh(:)
        integer, intent(in) :: k0, nn
        real(dp), intent(inout), contiguous :: dx(:), dy(:), dz(:), rr(:)
        integer :: k, j
        !GCC$ novector
        do k = 1, nn
            j = neigh(k0 + k)
            dx(k) = xi - x(1, j); dy(k) = yi - x(2, j); dz(k) = zi - x(3, j)
        end do
        do k = 1, nn
            rr(k) = dx(k)*dx(k) + dy(k)*dy(k) + dz(k)*dz(k)
        end do
    end subroutine separations

    !> One type: one density table. Per atom: one scalar pass gathers the separations, forms the
    !> squared distances and compacts the pairs inside the cutoff without branches (the list holds
    !> the skin shell too: a branch there is mispredicted about half the time), then their knots
    !> and offsets in a vectorised pass, then the table lookups and the scatter to rho(j). The
    !> partners inside the cutoff are kept for the force pass: cj(cfirst(i):cfirst(i+1)-1).
    subroutine density_one(nlocal, x, first, neigh, cutsq, rdr, nr, s, rho, cj, cfirst, pp, mm)
        integer, intent(in) :: nlocal, nr
        real(dp), intent(in) :: x(3, *)     ! explicit shape: constant stride in the gathers
        real(dp), intent(in) :: s(4, *)     ! density records (rho c3..c6) per knot
        integer, intent(in), contiguous :: first(:), neigh(:)
        real(dp), intent(in) :: cutsq, rdr
        real(dp), intent(inout), contiguous :: rho(:)
        integer, intent(inout), contiguous :: cj(:), cfirst(:)
        real(dp), intent(inout), contiguous :: pp(:)
        integer, intent(inout), contiguous :: mm(:)
        integer :: i, j, k, m, k0, nn, nin, c
        real(dp) :: xi, yi, zi, p, v, acc, top
        top = nr - 1
        c = 0
        cfirst(1) = 1
        do i = 1, nlocal
            xi = x(1, i); yi = x(2, i); zi = x(3, i)
            k0 = first(i) - 1
            nn = first(i + 1) - first(i)
            nin = 0
            call gather_inside(xi, yi, zi, x, neigh, k0, nn, cutsq, cj, c, pp, nin)
            do k = 1, nin
                p = sqrt(pp(k))*rdr + 1
                m = int(min(p, top))
                mm(k) = m
                pp(k) = min(p - m, 1.0_dp)
            end do
            acc = 0
            do k = 1, nin
                m = mm(k); p = pp(k)
                v = ((s(1, m)*p + s(2, m))*p + s(3, m))*p + s(4, m)
                acc = acc + v
                j = cj(c + k)
                rho(j) = rho(j) + v
            end do
            rho(i) = rho(i) + acc
            c = c + nin
            cfirst(i + 1) = c + 1
        end do
    end subroutine density_one

    !> The density passes' gather: of the nn partners j = neigh(k0 + k) of the atom at (xi, yi, zi),
    !> those inside the cutoff appended to cj(c + nin + 1 :) and their squared distances to
    !> pp(nin + 1 :), nin counting them; one scalar pass without branches (the list holds the skin
    !> shell too: a branch there is mispredicted about half the time).
    !> With AVX-512 the gather is eam_simd.c's (eight partners gathered, tested and compacted at a
    !> time; the same pairs, distances and order).
    subroutine gather_inside(xi, yi, zi, x, neigh, k0, nn, cutsq, cj, c, pp, nin)
        real(dp), intent(in) :: xi, yi, zi, cutsq
        real(dp), intent(in) :: x(3, *)
        integer, intent(in), contiguous :: neigh(:)
        integer, intent(in) :: k0, nn, c
        integer, intent(inout), contiguous :: cj(:)
        real(dp), intent(inout), contiguous :: pp(:)
        integer, intent(inout) :: nin
        integer :: k, j
        real(dp) :: ddx, ddy, ddz, rsq
        if (nn > 0) then
            k = c_gather_inside(xi, yi, zi, x, neigh(k0 + 1:), nn, cutsq, cj(c + nin + 1:), pp(nin + 1:))
            if (k >= 0) then
                nin = nin + k
                return
            end if
        end if
        !GCC$ novector
        do k = 1, nn
            j = neigh(k0 + k)
            ddx = xi - x(1, j); ddy = yi - x(2, j); ddz = zi - x(3, j)
            rsq = ddx*ddx + ddy*ddy + ddz*ddz
            cj(c + nin + 1) = j
            pp(nin + 1) = rsq
            nin = nin + merge(1, 0, rsq < cutsq)
        end do
    end subroutine gather_inside

    !> Several types: rho_i += rho_ba(r), rho_j += rho_ab(r) (a = type i, b = type j), staged as
    !> density_one, segment by segment of each row ordered by type (tfirst: the list's type_order),
    !> so that the tables are chosen once per segment: s holds one table per density function (the
    !> one-type records), rho_ba at column oi(b, a) + knot, rho_ab at oj(b, a) + knot; a pair whose
    !> two densities are one function (within a type, and eam/alloy's types of one element) reads
    !> one record and adds its value to both atoms, others read two (for CuNi.eam.alloy the table is
    !> 32 KB, where one 64-byte record per pair type and knot took 128 KB).
    !> The partners inside the cutoff are kept by segment for the force pass (cj, cseg, and cfirst).
    subroutine density_types(nlocal, nt, x, type, tfirst, neigh, cutsq, rdr, nr, oi, oj, s, rho, cj, cfirst, cseg, &
                             pp, mm)
        integer, intent(in) :: nlocal, nt, nr
        real(dp), intent(in) :: x(3, *)
        real(dp), intent(in) :: s(4, *)
        integer, intent(in), contiguous :: type(:), tfirst(:), neigh(:), oi(:, :), oj(:, :)
        real(dp), intent(in) :: cutsq, rdr
        real(dp), intent(inout), contiguous :: rho(:)
        integer, intent(inout), contiguous :: cj(:), cfirst(:), cseg(:)
        real(dp), intent(inout), contiguous :: pp(:)
        integer, intent(inout), contiguous :: mm(:)
        integer :: i, j, k, m, k0, nn, nin, c, ti, b, g, o, o2
        real(dp) :: xi, yi, zi, p, v, acc, top
        top = nr - 1
        c = 0
        cfirst(1) = 1
        cseg(1) = 1
        do i = 1, nlocal
            xi = x(1, i); yi = x(2, i); zi = x(3, i)
            ti = type(i)
            g = (i - 1)*nt
            ! the atom's segments end to end
            nin = 0
            do b = 1, nt
                k0 = tfirst(g + b) - 1
                nn = tfirst(g + b + 1) - tfirst(g + b)
                call gather_inside(xi, yi, zi, x, neigh, k0, nn, cutsq, cj, c, pp, nin)
                cseg(g + b + 1) = c + nin + 1
            end do
            ! knots of the whole row in one vectorised pass (the offsets are the segments')
            do k = 1, nin
                p = sqrt(pp(k))*rdr + 1
                m = int(min(p, top))
                mm(k) = m
                pp(k) = min(p - m, 1.0_dp)
            end do
            acc = 0
            do b = 1, nt
                o = oi(b, ti)
                o2 = oj(b, ti)
                if (o == o2) then
                    do k = cseg(g + b) - c, cseg(g + b + 1) - 1 - c
                        m = mm(k) + o; p = pp(k)
                        v = ((s(1, m)*p + s(2, m))*p + s(3, m))*p + s(4, m)
                        acc = acc + v
                        j = cj(c + k)
                        rho(j) = rho(j) + v
                    end do
                else
                    do k = cseg(g + b) - c, cseg(g + b + 1) - 1 - c
                        m = mm(k) + o; p = pp(k)
                        acc = acc + (((s(1, m)*p + s(2, m))*p + s(3, m))*p + s(4, m))
                        m = mm(k) + o2
                        j = cj(c + k)
                        rho(j) = rho(j) + (((s(1, m)*p + s(2, m))*p + s(3, m))*p + s(4, m))
                    end do
                end if
            end do
            rho(i) = rho(i) + acc
            c = c + nin
            cfirst(i + 1) = c + 1
        end do
    end subroutine density_types

    !> The pairs inside the cutoff as the density passes keep them (for a force pass not preceded by
    !> one), by segment: the nt segments of each atom's row, neigh(first(g) : first(g+1)-1) (g =
    !> (i-1) nt + b; nt = 1: the rows, first = the list's), to cj(cfirst(g) : cfirst(g+1)-1).
    subroutine inside_pairs(nlocal, nt, x, first, neigh, cutsq, cj, cfirst, dx, dy, dz, rr)
        integer, intent(in) :: nlocal, nt
        real(dp), intent(in), contiguous :: x(:, :)
        integer, intent(in), contiguous :: first(:), neigh(:)
        real(dp), intent(in) :: cutsq
        integer, intent(inout), contiguous :: cj(:), cfirst(:)
        real(dp), intent(inout), contiguous :: dx(:), dy(:), dz(:), rr(:)
        integer :: i, k, k0, nn, c, g
        c = 0
        cfirst(1) = 1
        do i = 1, nlocal
            do g = (i - 1)*nt + 1, i*nt
                k0 = first(g) - 1
                nn = first(g + 1) - first(g)
                call separations(x(1, i), x(2, i), x(3, i), x, neigh, k0, nn, dx, dy, dz, rr)
                do k = 1, nn
                    if (rr(k) < cutsq) then
                        c = c + 1
                        cj(c) = neigh(k0 + k)
                    end if
                end do
                cfirst(g + 1) = c + 1
            end do
        end do
    end subroutine inside_pairs

    !> Room for the pairs inside the cutoff: at most the list's length.
    subroutine reserve_pairs(self, nlocal, first)
        type(eam_t), intent(inout) :: self
        integer, intent(in) :: nlocal
        integer, intent(in), contiguous :: first(:)
        integer :: n
        n = first(nlocal + 1)
        if (allocated(self%cj)) then
            if (size(self%cj) < n .or. size(self%cfirst) < nlocal + 1) deallocate (self%cj, self%cfirst)
        end if
        if (.not. allocated(self%cj)) allocate (self%cj(n + n/4 + 16), self%cfirst(nlocal + nlocal/4 + 16))
        if (self%ntypes > 1) call reserve(self%cseg, self%ntypes*nlocal + 1)
    end subroutine reserve_pairs

    !> F'(rho) (and F) of owned atoms; lo, hi: extremes of rho.
    subroutine embed_kernel(n, type, t2f, fspl, rdrho, nrho, rhomax, rho, want_energy, fp, energy, lo, hi)
        integer, intent(in) :: n, nrho
        integer, intent(in), contiguous :: type(:), t2f(:)
        real(dp), intent(in), contiguous :: fspl(:, :, :), rho(:)
        real(dp), intent(in) :: rdrho, rhomax
        logical, intent(in) :: want_energy
        real(dp), intent(inout), contiguous :: fp(:)
        real(dp), intent(inout) :: energy
        real(dp), intent(out) :: lo, hi
        integer :: i, m, k
        real(dp) :: p, top, r, e, phi, ce
        top = nrho - 1
        e = 0; ce = 0
        lo = huge(1.0_dp); hi = -huge(1.0_dp)
        do i = 1, n
            k = t2f(type(i))
            r = rho(i)
            p = r*rdrho + 1
            m = int(max(1.0_dp, min(p, top)))
            p = min(p - m, 1.0_dp)
            fp(i) = (fspl(1, m, k)*p + fspl(2, m, k))*p + fspl(3, m, k)
            if (want_energy) then
                phi = ((fspl(4, m, k)*p + fspl(5, m, k))*p + fspl(6, m, k))*p + fspl(7, m, k)
                if (r > rhomax) phi = phi + fp(i)*(r - rhomax)
                call comp_add(e, ce, phi)
            end if
            lo = min(lo, r); hi = max(hi, r)
        end do
        energy = energy + (e + ce)
    end subroutine embed_kernel

    !> One type: psi'(r) = (fp_i + fp_j) rho'(r) + phi'(r), phi = z/r, phi' = (z' - phi)/r, over the
    !> pairs inside the cutoff (cj, cfirst). The pairs of consecutive atoms are taken in blocks of
    !> about block_pairs (whole atoms; long rows keep the vector loops busy): gathered separations
    !> and fp_i + fp_j, a vectorised pass for r^2, r, 1/r, the knot and the offset, the table
    !> lookups (one record per pair, t = ztab), a vectorised pass for the pair forces, then the
    !> scatter (Newton's third law) with the sums for the atoms i.
    subroutine force_one(nlocal, x, f, cj, cfirst, rdr, nr, t, fp, want_energy, energy, virial, &
                         dx, dy, dz, rr, pp, rinv, fj, ph, mm)
        integer, intent(in) :: nlocal, nr
        real(dp), intent(in) :: x(3, *)     ! explicit shape: constant stride in the gathers and scatters
        real(dp), intent(in), contiguous :: t(:, :), fp(:)
        real(dp), intent(inout) :: f(3, *)
        integer, intent(in), contiguous :: cj(:), cfirst(:)
        real(dp), intent(in) :: rdr
        logical, intent(in) :: want_energy
        real(dp), intent(inout) :: energy, virial
        real(dp), intent(inout), contiguous :: dx(:), dy(:), dz(:), rr(:), pp(:), rinv(:), fj(:), ph(:)
        integer, intent(inout), contiguous :: mm(:)
        integer :: i, i0, i1, j, k, m, c, c0, n
        real(dp) :: xi, yi, zi, fpi, p, r, rp, z, zp, phi, fpair, fxi, fyi, fzi, e, w, top, ei, ce
        top = nr - 1
        e = 0; w = 0; ce = 0
        i0 = 1
        do while (i0 <= nlocal)
            ! the block: atoms i0..i1, pairs c0+1..c0+n (at least one atom; the rows fit: reserve_work)
            c0 = cfirst(i0) - 1
            i1 = i0
            do while (i1 < nlocal)
                if (cfirst(i1 + 2) - 1 - c0 > block_pairs) exit
                i1 = i1 + 1
            end do
            n = cfirst(i1 + 1) - 1 - c0
            do i = i0, i1
                xi = x(1, i); yi = x(2, i); zi = x(3, i); fpi = fp(i)
                !GCC$ novector
                do c = cfirst(i), cfirst(i + 1) - 1
                    k = c - c0
                    j = cj(c)
                    dx(k) = xi - x(1, j); dy(k) = yi - x(2, j); dz(k) = zi - x(3, j)
                    fj(k) = fpi + fp(j)
                end do
            end do
            do k = 1, n
                rr(k) = dx(k)*dx(k) + dy(k)*dy(k) + dz(k)*dz(k)
                r = sqrt(rr(k))
                rinv(k) = 1/r
                p = r*rdr + 1
                m = int(min(p, top))
                mm(k) = m
                pp(k) = min(p - m, 1.0_dp)
            end do
            ! lookups (scalar: a vectorised gather of the record costs more): rp -> fj (times fp_i + fp_j),
            ! z' -> pp, z -> ph; rr keeps r^2, rinv becomes fpair
            !GCC$ novector
            do k = 1, n
                m = mm(k); p = pp(k)
                rp = (t(1, m)*p + t(2, m))*p + t(3, m)
                zp = ((3*t(4, m)*p + 2*t(5, m))*p + t(6, m))*rdr
                z = ((t(4, m)*p + t(5, m))*p + t(6, m))*p + t(7, m)
                fj(k) = fj(k)*rp
                pp(k) = zp
                ph(k) = z
            end do
            do k = 1, n
                phi = ph(k)*rinv(k)
                ph(k) = phi
                fpair = -(fj(k) + (pp(k)*rinv(k) - phi*rinv(k)))*rinv(k)
                rinv(k) = fpair
                dx(k) = dx(k)*fpair; dy(k) = dy(k)*fpair; dz(k) = dz(k)*fpair
            end do
            if (want_energy) then
                ! pair energies summed per atom, the atoms' sums compensated (see the top)
                do i = i0, i1
                    ei = 0
                    do c = cfirst(i), cfirst(i + 1) - 1
                        k = c - c0
                        ei = ei + ph(k)
                        w = w + rr(k)*rinv(k)
                    end do
                    call comp_add(e, ce, ei)
                end do
            end if
            do i = i0, i1
                fxi = 0; fyi = 0; fzi = 0
                !GCC$ novector
                do c = cfirst(i), cfirst(i + 1) - 1
                    k = c - c0
                    j = cj(c)
                    f(1, j) = f(1, j) - dx(k); f(2, j) = f(2, j) - dy(k); f(3, j) = f(3, j) - dz(k)
                    fxi = fxi + dx(k); fyi = fyi + dy(k); fzi = fzi + dz(k)
                end do
                f(1, i) = f(1, i) + fxi; f(2, i) = f(2, i) + fyi; f(3, i) = f(3, i) + fzi
            end do
            i0 = i1 + 1
        end do
        energy = energy + (e + ce); virial = virial + w
    end subroutine force_one

    !> Several types: psi'(r) = fp_i rho_ba'(r) + fp_j rho_ab'(r) + phi_ab'(r) (a = type i, b = type
    !> j), staged and blocked as force_one, the lookups segment by segment of the density pass's
    !> pairs (cseg), from the tables of build_pair_tables: rd (rho' c0..c2 per density function;
    !> rho_ba' at column oi(b, a) + knot, rho_ab' at oj(b, a) + knot) and zt (z c3..c6 per r phi
    !> function, z_ab at oz(b, a) + knot); z' = ((3 c3 p + 2 c4) p + c5)/dr. A pair whose two
    !> densities are one function (within a type) reads rho' once and multiplies it by fp_i + fp_j.
    subroutine force_types(nlocal, nt, x, f, type, cj, cfirst, cseg, rdr, nr, oi, oj, oz, rd, zt, fp, want_energy, &
                           energy, virial, dx, dy, dz, rr, pp, rinv, fj, ph, mm)
        integer, intent(in) :: nlocal, nt, nr
        real(dp), intent(in) :: x(3, *)
        real(dp), intent(in), contiguous :: fp(:)
        real(dp), intent(in) :: rd(3, *), zt(4, *)
        real(dp), intent(inout) :: f(3, *)
        integer, intent(in), contiguous :: type(:), cj(:), cfirst(:), cseg(:), oi(:, :), oj(:, :), oz(:, :)
        real(dp), intent(in) :: rdr
        logical, intent(in) :: want_energy
        real(dp), intent(inout) :: energy, virial
        real(dp), intent(inout), contiguous :: dx(:), dy(:), dz(:), rr(:), pp(:), rinv(:), fj(:), ph(:)
        integer, intent(inout), contiguous :: mm(:)
        integer :: i, i0, i1, j, k, m, c, c0, n, ti, b, g, o, o2, o3
        real(dp) :: xi, yi, zi, fpi, p, r, rp, rpi, rpj, z, zp, phi, fpair, fxi, fyi, fzi, e, w, top, ei, ce
        top = nr - 1
        e = 0; w = 0; ce = 0
        i0 = 1
        do while (i0 <= nlocal)
            c0 = cfirst(i0) - 1
            i1 = i0
            do while (i1 < nlocal)
                if (cfirst(i1 + 2) - 1 - c0 > block_pairs) exit
                i1 = i1 + 1
            end do
            n = cfirst(i1 + 1) - 1 - c0
            do i = i0, i1
                xi = x(1, i); yi = x(2, i); zi = x(3, i)
                !GCC$ novector
                do c = cfirst(i), cfirst(i + 1) - 1
                    k = c - c0
                    j = cj(c)
                    dx(k) = xi - x(1, j); dy(k) = yi - x(2, j); dz(k) = zi - x(3, j)
                    fj(k) = fp(j)
                end do
            end do
            do k = 1, n
                rr(k) = dx(k)*dx(k) + dy(k)*dy(k) + dz(k)*dz(k)
                r = sqrt(rr(k))
                rinv(k) = 1/r
                p = r*rdr + 1
                m = int(min(p, top))
                mm(k) = m
                pp(k) = min(p - m, 1.0_dp)
            end do
            ! lookups (scalar: see force_one), segment by segment: (fp_i + fp_j) rho_aa' or
            ! fp_i rho_ba' + fp_j rho_ab' -> fj; z' -> pp, z -> ph
            do i = i0, i1
                fpi = fp(i)
                ti = type(i)
                do b = 1, nt
                    g = (i - 1)*nt + b
                    o = oi(b, ti); o2 = oj(b, ti); o3 = oz(b, ti)
                    if (o == o2) then
                        !GCC$ novector
                        do k = cseg(g) - c0, cseg(g + 1) - 1 - c0
                            m = mm(k); p = pp(k)
                            rp = (rd(1, m + o)*p + rd(2, m + o))*p + rd(3, m + o)
                            zp = ((3*zt(1, m + o3)*p + 2*zt(2, m + o3))*p + zt(3, m + o3))*rdr
                            z = ((zt(1, m + o3)*p + zt(2, m + o3))*p + zt(3, m + o3))*p + zt(4, m + o3)
                            fj(k) = (fpi + fj(k))*rp
                            pp(k) = zp
                            ph(k) = z
                        end do
                    else
                        !GCC$ novector
                        do k = cseg(g) - c0, cseg(g + 1) - 1 - c0
                            m = mm(k); p = pp(k)
                            rpi = (rd(1, m + o)*p + rd(2, m + o))*p + rd(3, m + o)
                            rpj = (rd(1, m + o2)*p + rd(2, m + o2))*p + rd(3, m + o2)
                            zp = ((3*zt(1, m + o3)*p + 2*zt(2, m + o3))*p + zt(3, m + o3))*rdr
                            z = ((zt(1, m + o3)*p + zt(2, m + o3))*p + zt(3, m + o3))*p + zt(4, m + o3)
                            fj(k) = fpi*rpi + fj(k)*rpj
                            pp(k) = zp
                            ph(k) = z
                        end do
                    end if
                end do
            end do
            do k = 1, n
                phi = ph(k)*rinv(k)
                ph(k) = phi
                fpair = -(fj(k) + (pp(k)*rinv(k) - phi*rinv(k)))*rinv(k)
                rinv(k) = fpair
                dx(k) = dx(k)*fpair; dy(k) = dy(k)*fpair; dz(k) = dz(k)*fpair
            end do
            if (want_energy) then
                ! pair energies summed per atom, the atoms' sums compensated (see the top)
                do i = i0, i1
                    ei = 0
                    do c = cfirst(i), cfirst(i + 1) - 1
                        k = c - c0
                        ei = ei + ph(k)
                        w = w + rr(k)*rinv(k)
                    end do
                    call comp_add(e, ce, ei)
                end do
            end if
            do i = i0, i1
                fxi = 0; fyi = 0; fzi = 0
                !GCC$ novector
                do c = cfirst(i), cfirst(i + 1) - 1
                    k = c - c0
                    j = cj(c)
                    f(1, j) = f(1, j) - dx(k); f(2, j) = f(2, j) - dy(k); f(3, j) = f(3, j) - dz(k)
                    fxi = fxi + dx(k); fyi = fyi + dy(k); fzi = fzi + dz(k)
                end do
                f(1, i) = f(1, i) + fxi; f(2, i) = f(2, i) + fyi; f(3, i) = f(3, i) + fzi
            end do
            i0 = i1 + 1
        end do
        energy = energy + (e + ce); virial = virial + w
    end subroutine force_types

end module terrace_eam
