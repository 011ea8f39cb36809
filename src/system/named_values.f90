!> Named scalars of the run state (integer, real or logical, by name): what an integrator, a
!> thermostat or the run control saves at a checkpoint and reads back on a restart. The checkpoint
!> writer stores them as attributes of /state (terrace_checkpoint); nothing here knows the file.
module terrace_named_values
    use terrace_kinds, only: dp, i8
    use terrace_text, only: int_text
    implicit none
    private

    !> The named values, in the order they were put.
    type, public :: named_values_t
        character(len=40), allocatable :: names(:)
        integer(i8), allocatable :: ival(:)
        real(dp), allocatable :: rval(:)
        logical, allocatable :: is_int(:)
        integer :: n = 0
    contains
        procedure :: put => values_put
        procedure :: get_i => values_get_i
        procedure :: get_r => values_get_r
        procedure :: get_l => values_get_l
        procedure :: has => values_has
        procedure :: exchange => values_exchange
        procedure :: put_reals => values_put_reals
        procedure :: get_reals => values_get_reals
        procedure, private :: slot => values_slot
        procedure, private :: find => values_find
    end type named_values_t

contains

    integer function values_slot(self, name) result(k)
        class(named_values_t), intent(inout) :: self
        character(len=*), intent(in) :: name
        character(len=40), allocatable :: n2(:)
        integer(i8), allocatable :: i2(:)
        real(dp), allocatable :: r2(:)
        logical, allocatable :: b2(:)
        do k = 1, self%n
            if (self%names(k) == name) return
        end do
        if (.not. allocated(self%names)) then
            allocate (self%names(32), self%ival(32), self%rval(32), self%is_int(32))
        else if (self%n == size(self%names)) then
            allocate (n2(2*self%n), i2(2*self%n), r2(2*self%n), b2(2*self%n))
            n2(1:self%n) = self%names(1:self%n); i2(1:self%n) = self%ival(1:self%n)
            r2(1:self%n) = self%rval(1:self%n); b2(1:self%n) = self%is_int(1:self%n)
            call move_alloc(n2, self%names); call move_alloc(i2, self%ival)
            call move_alloc(r2, self%rval); call move_alloc(b2, self%is_int)
        end if
        self%n = self%n + 1; k = self%n
        self%names(k) = name; self%ival(k) = 0; self%rval(k) = 0
    end function values_slot

    !> Store v (integer(i8), real(dp) or logical, kept as 0/1) under name.
    subroutine values_put(self, name, v)
        class(named_values_t), intent(inout) :: self
        character(len=*), intent(in) :: name
        class(*), intent(in) :: v
        integer :: k
        k = self%slot(name)
        select type (v)
        type is (integer(i8))
            self%ival(k) = v; self%is_int(k) = .true.
        type is (real(dp))
            self%rval(k) = v; self%is_int(k) = .false.
        type is (logical)
            self%ival(k) = merge(1_i8, 0_i8, v); self%is_int(k) = .true.
        end select
    end subroutine values_put

    !> One value of a checkpoint's state, real(dp), integer(i8) or logical: put when saving, else
    !> read back into x (ok false when it is missing), so that one list of names serves both ways.
    subroutine values_exchange(self, name, x, saving, ok)
        class(named_values_t), intent(inout) :: self
        character(len=*), intent(in) :: name
        class(*), intent(inout) :: x
        logical, intent(in) :: saving
        logical, intent(inout) :: ok
        if (saving) then
            call self%put(name, x)
            return
        end if
        select type (x)
        type is (real(dp))
            x = self%get_r(name, ok)
        type is (integer(i8))
            x = self%get_i(name, ok)
        type is (logical)
            x = self%get_l(name, ok)
        end select
    end subroutine values_exchange

    !> x(1), x(2), ... under prefix//'1', prefix//'2', ... (a chain's positions, say).
    subroutine values_put_reals(self, prefix, x)
        class(named_values_t), intent(inout) :: self
        character(len=*), intent(in) :: prefix
        real(dp), intent(in) :: x(:)
        integer :: j
        do j = 1, size(x)
            call self%put(prefix//int_text(j), x(j))
        end do
    end subroutine values_put_reals

    !> x(:) back from the names values_put_reals gave them (ok false when one is missing).
    subroutine values_get_reals(self, prefix, x, ok)
        class(named_values_t), intent(in) :: self
        character(len=*), intent(in) :: prefix
        real(dp), intent(inout) :: x(:)
        logical, intent(inout) :: ok
        integer :: j
        do j = 1, size(x)
            x(j) = self%get_r(prefix//int_text(j), ok)
        end do
    end subroutine values_get_reals

    logical function values_has(self, name)
        class(named_values_t), intent(in) :: self
        character(len=*), intent(in) :: name
        values_has = any(self%names(1:self%n) == name)
    end function values_has

    !> The value called name; ok becomes .false. (and stays so) when it is missing.
    integer(i8) function values_get_i(self, name, ok) result(v)
        class(named_values_t), intent(in) :: self
        character(len=*), intent(in) :: name
        logical, intent(inout) :: ok
        integer :: k
        v = 0
        k = self%find(name, .true., ok)
        if (k > 0) v = self%ival(k)
    end function values_get_i

    real(dp) function values_get_r(self, name, ok) result(v)
        class(named_values_t), intent(in) :: self
        character(len=*), intent(in) :: name
        logical, intent(inout) :: ok
        integer :: k
        v = 0
        k = self%find(name, .false., ok)
        if (k > 0) v = self%rval(k)
    end function values_get_r

    !> The slot of name holding an integer (is_int) or a real; 0, and ok = .false., when none does.
    integer function values_find(self, name, is_int, ok) result(k)
        class(named_values_t), intent(in) :: self
        character(len=*), intent(in) :: name
        logical, intent(in) :: is_int
        logical, intent(inout) :: ok
        do k = 1, self%n
            if (self%names(k) == name .and. (self%is_int(k) .eqv. is_int)) return
        end do
        k = 0
        ok = .false.
    end function values_find

    logical function values_get_l(self, name, ok) result(v)
        class(named_values_t), intent(in) :: self
        character(len=*), intent(in) :: name
        logical, intent(inout) :: ok
        v = self%get_i(name, ok) /= 0
    end function values_get_l

end module terrace_named_values
