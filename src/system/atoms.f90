!> Atom storage: owned atoms 1..nlocal, then ghosts nlocal+1..nlocal+nghost, in contiguous
!> structure-of-arrays form (x(3,n), v(3,n), f(3,n)). Ghosts carry positions, velocities and types
!> (velocities so that a ray x + t v can be followed on every rank without messages).
module terrace_atoms
    use terrace_kinds, only: dp, i8
    implicit none
    private

    type, public :: atoms_t
        integer :: nlocal = 0
        integer :: nghost = 0
        integer :: ntypes = 1
        real(dp), allocatable :: x(:, :), v(:, :), f(:, :)
        integer, allocatable :: type(:)
        integer(i8), allocatable :: id(:)
        integer, allocatable :: image(:, :)
        real(dp), allocatable :: mass(:)            !< per type
        !> Per-atom masses (meshes: lumped nodal masses): mass_of_id(id) for every atom of the scene,
        !> copied into rmass(1:nall) in local order at every rebuild (refresh_rmass). Only when
        !> per_atom_mass; otherwise mass(type(i)) holds.
        logical :: per_atom_mass = .false.
        real(dp), allocatable :: mass_of_id(:), rmass(:)
        !> A per-atom time kept by a thermostat (Andersen with velocity Verlet: the atom's next
        !> collision time), carried with the owned atom when atoms are reordered or migrate.
        !> Allocated only by its user (enable_clock); clock_unset until the user sets it.
        real(dp), allocatable :: clock(:)
    contains
        procedure :: reserve => atoms_reserve
        procedure :: append => atoms_append
        procedure :: nall => atoms_nall
        procedure :: copy_owned => atoms_copy_owned
        procedure :: permute_owned => atoms_permute_owned
        procedure :: refresh_rmass => atoms_refresh_rmass
        procedure :: enable_clock => atoms_enable_clock
    end type atoms_t

    real(dp), parameter, public :: clock_unset = -1   !< a clock not set yet (after a start or a restart)

contains

    pure integer function atoms_nall(self)
        class(atoms_t), intent(in) :: self
        atoms_nall = self%nlocal + self%nghost
    end function atoms_nall

    !> Make room for at least n atoms (owned + ghost), keeping the data.
    subroutine atoms_reserve(self, n)
        class(atoms_t), intent(inout) :: self
        integer, intent(in) :: n
        integer :: cap, keep
        real(dp), allocatable :: r2(:, :), r1(:)
        integer, allocatable :: i1(:), i2(:, :)
        integer(i8), allocatable :: l1(:)
        if (allocated(self%x)) then
            cap = size(self%x, 2)
            if (cap >= n) return
        else
            cap = 0
        end if
        keep = self%nlocal + self%nghost
        cap = max(n, cap + cap/2, 64)
        allocate (r2(3, cap)); r2 = 0
        if (keep > 0) r2(:, 1:keep) = self%x(:, 1:keep)
        call move_alloc(r2, self%x)
        allocate (r2(3, cap)); r2 = 0
        if (keep > 0) r2(:, 1:keep) = self%v(:, 1:keep)
        call move_alloc(r2, self%v)
        allocate (r2(3, cap)); r2 = 0
        if (keep > 0) r2(:, 1:keep) = self%f(:, 1:keep)
        call move_alloc(r2, self%f)
        allocate (i1(cap)); i1 = 1
        if (keep > 0) i1(1:keep) = self%type(1:keep)
        call move_alloc(i1, self%type)
        allocate (l1(cap)); l1 = 0
        if (keep > 0) l1(1:keep) = self%id(1:keep)
        call move_alloc(l1, self%id)
        allocate (i2(3, cap)); i2 = 0
        if (keep > 0) i2(:, 1:keep) = self%image(:, 1:keep)
        call move_alloc(i2, self%image)
        if (allocated(self%clock)) then
            allocate (r1(cap)); r1 = clock_unset
            if (keep > 0) r1(1:keep) = self%clock(1:keep)
            call move_alloc(r1, self%clock)
        end if
    end subroutine atoms_reserve

    !> Allocate the per-atom clock (every entry clock_unset), if not yet there.
    subroutine atoms_enable_clock(self)
        class(atoms_t), intent(inout) :: self
        if (allocated(self%clock)) return
        call self%reserve(max(self%nlocal + self%nghost, 1))
        allocate (self%clock(size(self%x, 2)))
        self%clock = clock_unset
    end subroutine atoms_enable_clock

    !> Append an owned atom (only while there are no ghosts).
    subroutine atoms_append(self, x, v, type, id, image)
        class(atoms_t), intent(inout) :: self
        real(dp), intent(in) :: x(3), v(3)
        integer, intent(in) :: type, image(3)
        integer(i8), intent(in) :: id
        integer :: n
        n = self%nlocal + 1
        call self%reserve(n)
        self%x(:, n) = x; self%v(:, n) = v; self%f(:, n) = 0
        self%type(n) = type; self%id(n) = id; self%image(:, n) = image
        self%nlocal = n
    end subroutine atoms_append

    !> Copy owned atom src onto slot dst.
    subroutine atoms_copy_owned(self, src, dst)
        class(atoms_t), intent(inout) :: self
        integer, intent(in) :: src, dst
        self%x(:, dst) = self%x(:, src); self%v(:, dst) = self%v(:, src); self%f(:, dst) = self%f(:, src)
        self%type(dst) = self%type(src); self%id(dst) = self%id(src); self%image(:, dst) = self%image(:, src)
        if (allocated(self%clock)) self%clock(dst) = self%clock(src)
    end subroutine atoms_copy_owned

    !> Reorder owned atoms: new atom k is old atom perm(k). `work` must hold 3*nlocal reals.
    subroutine atoms_permute_owned(self, perm)
        class(atoms_t), intent(inout) :: self
        integer, intent(in) :: perm(:)
        integer :: n
        n = self%nlocal
        self%x(:, 1:n) = self%x(:, perm(1:n))
        self%v(:, 1:n) = self%v(:, perm(1:n))
        self%f(:, 1:n) = self%f(:, perm(1:n))
        self%type(1:n) = self%type(perm(1:n))
        self%id(1:n) = self%id(perm(1:n))
        self%image(:, 1:n) = self%image(:, perm(1:n))
        if (allocated(self%clock)) self%clock(1:n) = self%clock(perm(1:n))
    end subroutine atoms_permute_owned

    !> rmass(1:nall) from mass_of_id in the current local order (after migration and halo).
    subroutine atoms_refresh_rmass(self)
        class(atoms_t), intent(inout) :: self
        integer :: i, n
        if (.not. self%per_atom_mass) return
        n = self%nall()
        if (allocated(self%rmass)) then
            if (size(self%rmass) < n) deallocate (self%rmass)
        end if
        if (.not. allocated(self%rmass)) allocate (self%rmass(max(n + n/4, 16)))
        do i = 1, n
            self%rmass(i) = self%mass_of_id(self%id(i))
        end do
    end subroutine atoms_refresh_rmass

end module terrace_atoms
