!> An indexed 4-ary min-heap of event times: one slot per atom (its earliest predicted event) and
!> a few more (the run's schedule: samples, frames, the end). Changing a slot's time moves it up
!> or down in O(log n); the earliest slot is at the top. Ties are broken by the slot number, so
!> that the order of events is the same on every rank and every run (and whatever the heap's
!> shape: the order (time, slot) is total). An event that a partner's later change has made stale
!> is not searched for: the event loop checks the partner's event counter when the slot comes to
!> the top (lazy invalidation) and predicts the slot again.
!>
!> Layout for large queues (10^6 atoms: the heap no longer fits the caches): the time and slot of
!> each heap position are stored at that position (key, slot), so that a comparison reads the
!> heap arrays only, not the slot's time elsewhere in memory; four children per node halve the
!> levels of a binary heap and sit next to each other (one or two cache lines per level).
module terrace_event_queue
    use terrace_kinds, only: dp
    implicit none
    private

    type, public :: event_queue_t
        integer :: n = 0
        real(dp), allocatable :: t(:)       !< (slot) event time
        real(dp), allocatable :: key(:)     !< heap position -> its slot's time
        integer, allocatable :: heap(:)     !< heap position -> slot
        integer, allocatable :: pos(:)      !< slot -> heap position
    contains
        procedure :: init => queue_init
        procedure :: set => queue_set
        procedure :: top => queue_top
        procedure :: check => queue_check
    end type event_queue_t

contains

    !> n slots, all at time huge (never).
    subroutine queue_init(self, n)
        class(event_queue_t), intent(inout) :: self
        integer, intent(in) :: n
        integer :: k
        if (allocated(self%t)) deallocate (self%t, self%key, self%heap, self%pos)
        allocate (self%t(n), self%key(n), self%heap(n), self%pos(n))
        self%n = n
        self%t = huge(1.0_dp)
        self%key = huge(1.0_dp)
        do k = 1, n
            self%heap(k) = k
            self%pos(k) = k
        end do
    end subroutine queue_init

    !> The slot with the earliest time (and the lowest number among equal times).
    pure integer function queue_top(self) result(slot)
        class(event_queue_t), intent(in) :: self
        slot = self%heap(1)
    end function queue_top

    !> Give slot the time t and restore the heap order. The children of position p are
    !> 4p - 2 .. 4p + 1, its parent (p + 2)/4.
    subroutine queue_set(self, slot, t)
        class(event_queue_t), intent(inout) :: self
        integer, intent(in) :: slot
        real(dp), intent(in) :: t
        integer :: p, q, c, c1, clast, s
        real(dp) :: old, tc
        old = self%t(slot)
        self%t(slot) = t
        p = self%pos(slot)
        if (t < old) then                                            ! moved earlier: sift up
            do while (p > 1)
                q = (p + 2)/4
                if (.not. earlier(t, slot, self%key(q), self%heap(q))) exit
                s = self%heap(q)
                self%heap(p) = s; self%key(p) = self%key(q); self%pos(s) = p
                p = q
            end do
        else                                                         ! sift down
            do
                c1 = 4*p - 2
                if (c1 > self%n) exit
                clast = min(c1 + 3, self%n)
                c = c1                                               ! the earliest child
                do q = c1 + 1, clast
                    if (earlier(self%key(q), self%heap(q), self%key(c), self%heap(c))) c = q
                end do
                tc = self%key(c); s = self%heap(c)
                if (.not. earlier(tc, s, t, slot)) exit
                self%heap(p) = s; self%key(p) = tc; self%pos(s) = p
                p = c
            end do
        end if
        self%heap(p) = slot; self%key(p) = t; self%pos(slot) = p
    end subroutine queue_set

    pure logical function earlier(ta, a, tb, b)
        real(dp), intent(in) :: ta, tb
        integer, intent(in) :: a, b
        earlier = ta < tb .or. (ta == tb .and. a < b)
    end function earlier

    !> The heap order holds, pos inverts heap and each position's key is its slot's time (for
    !> tests).
    logical function queue_check(self) result(ok)
        class(event_queue_t), intent(in) :: self
        integer :: p, q
        ok = .true.
        do p = 1, self%n
            ok = ok .and. self%pos(self%heap(p)) == p
            ok = ok .and. self%key(p) == self%t(self%heap(p))
            if (p > 1) then
                q = (p + 2)/4
                ok = ok .and. .not. earlier(self%key(p), self%heap(p), self%key(q), self%heap(q))
            end if
        end do
    end function queue_check

end module terrace_event_queue
