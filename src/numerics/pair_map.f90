!> A map from an atom pair (i < j, global indices) to a small integer (a stepped pair's region),
!> for the pairs not in region 0: open addressing with linear probing and backward-shift deletion
!> (no tombstones), capacity a power of two kept at most half full. Lookups and updates are O(1)
!> on average and allocate nothing; the table grows (a rehash) only when it would pass half full.
module terrace_pair_map
    use terrace_kinds, only: i8
    implicit none
    private

    type, public :: pair_map_t
        integer(i8) :: mask = -1
        integer(i8) :: used = 0
        integer(i8), allocatable :: key(:)     !< 0: empty; else (i - 1) * n + j
        integer, allocatable :: val(:)
        integer(i8) :: natoms = 0
    contains
        procedure :: init => map_init
        procedure :: get => map_get
        procedure :: put => map_put
        procedure :: count => map_count
    end type pair_map_t

contains

    !> Room for about `expected` pairs among natoms atoms.
    subroutine map_init(self, natoms, expected)
        class(pair_map_t), intent(inout) :: self
        integer(i8), intent(in) :: natoms, expected
        integer(i8) :: cap
        cap = 1024
        do while (cap < 2*expected)
            cap = 2*cap
        end do
        if (allocated(self%key)) deallocate (self%key, self%val)
        allocate (self%key(0:cap - 1), self%val(0:cap - 1))
        self%key = 0; self%val = 0
        self%mask = cap - 1
        self%used = 0
        self%natoms = natoms
    end subroutine map_init

    pure integer(i8) function pair_key(self, i, j) result(k)
        class(pair_map_t), intent(in) :: self
        integer, intent(in) :: i, j
        k = int(min(i, j) - 1, i8)*self%natoms + max(i, j)
    end function pair_key

    pure integer(i8) function home(self, k)
        class(pair_map_t), intent(in) :: self
        integer(i8), intent(in) :: k
        integer(i8) :: h
        h = ieor(k, ishft(k, -17))
        h = ieor(h*40503_i8, ishft(h, -29))     ! (keys < 2^40: no overflow)
        home = iand(h, self%mask)
    end function home

    !> The value of pair (i, j); 0 when absent.
    pure integer function map_get(self, i, j) result(v)
        class(pair_map_t), intent(in) :: self
        integer, intent(in) :: i, j
        integer(i8) :: k, p
        k = pair_key(self, i, j)
        p = home(self, k)
        v = 0
        do while (self%key(p) /= 0)
            if (self%key(p) == k) then
                v = self%val(p)
                return
            end if
            p = iand(p + 1, self%mask)
        end do
    end function map_get

    !> Set pair (i, j) to v; v = 0 removes it.
    recursive subroutine map_put(self, i, j, v)
        class(pair_map_t), intent(inout) :: self
        integer, intent(in) :: i, j, v
        integer(i8) :: k, p, q, h
        k = pair_key(self, i, j)
        p = home(self, k)
        do while (self%key(p) /= 0)
            if (self%key(p) == k) exit
            p = iand(p + 1, self%mask)
        end do
        if (self%key(p) == k) then
            if (v /= 0) then
                self%val(p) = v
                return
            end if
            ! backward-shift deletion: pull later members of the probe run into the hole
            self%used = self%used - 1
            q = p
            do
                q = iand(q + 1, self%mask)
                if (self%key(q) == 0) exit
                h = home(self, self%key(q))
                ! the entry at q may move to p if its home is not cyclically in (p, q]
                if (iand(q - h, self%mask) >= iand(q - p, self%mask)) then
                    self%key(p) = self%key(q); self%val(p) = self%val(q)
                    p = q
                end if
            end do
            self%key(p) = 0; self%val(p) = 0
            return
        end if
        if (v == 0) return
        if (2*(self%used + 1) > self%mask + 1) then
            call grow(self)
            call self%put(i, j, v)
            return
        end if
        self%key(p) = k; self%val(p) = v
        self%used = self%used + 1
    end subroutine map_put

    subroutine grow(self)
        class(pair_map_t), intent(inout) :: self
        integer(i8), allocatable :: oldk(:)
        integer, allocatable :: oldv(:)
        integer(i8) :: p, q, cap
        call move_alloc(self%key, oldk)
        call move_alloc(self%val, oldv)
        cap = 2*(self%mask + 1)
        allocate (self%key(0:cap - 1), self%val(0:cap - 1))
        self%key = 0; self%val = 0
        self%mask = cap - 1
        do p = 0, size(oldk, kind=i8) - 1
            if (oldk(p) == 0) cycle
            q = home(self, oldk(p))
            do while (self%key(q) /= 0)
                q = iand(q + 1, self%mask)
            end do
            self%key(q) = oldk(p); self%val(q) = oldv(p)
        end do
    end subroutine grow

    pure integer(i8) function map_count(self)
        class(pair_map_t), intent(in) :: self
        map_count = self%used
    end function map_count

end module terrace_pair_map
