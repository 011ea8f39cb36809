!> An indexed binary min-heap of event times: one slot per atom (its earliest predicted event) and
!> a few more (the run's schedule: samples, frames, the end). Changing a slot's time moves it up
!> or down in O(log n); the earliest slot is at the top. Ties are broken by the slot number, so
!> that the order of events is the same on every rank and every run. An event that a partner's
!> later change has made stale is not searched for: the event loop checks the partner's event
!> counter when the slot comes to the top (lazy invalidation) and predicts the slot again.
module terrace_event_queue
    use terrace_kinds, only: dp
    implicit none
    private

    type, public :: event_queue_t
        integer :: n = 0
        real(dp), allocatable :: t(:)       !< (slot) event time
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
        if (allocated(self%t)) deallocate (self%t, self%heap, self%pos)
        allocate (self%t(n), self%heap(n), self%pos(n))
        self%n = n
        self%t = huge(1.0_dp)
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

    !> Give slot the time t and restore the heap order.
    subroutine queue_set(self, slot, t)
        class(event_queue_t), intent(inout) :: self
        integer, intent(in) :: slot
        real(dp), intent(in) :: t
        integer :: p, q, c, s
        real(dp) :: old
        old = self%t(slot)
        self%t(slot) = t
        p = self%pos(slot)
        if (t < old) then                                            ! moved earlier: sift up
            do while (p > 1)
                q = p/2
                s = self%heap(q)
                if (.not. earlier(t, slot, self%t(s), s)) exit
                self%heap(p) = s; self%pos(s) = p
                p = q
            end do
        else                                                         ! sift down
            do
                c = 2*p
                if (c > self%n) exit
                if (c < self%n) then
                    if (earlier(self%t(self%heap(c + 1)), self%heap(c + 1), self%t(self%heap(c)), self%heap(c))) &
                        c = c + 1
                end if
                s = self%heap(c)
                if (.not. earlier(self%t(s), s, t, slot)) exit
                self%heap(p) = s; self%pos(s) = p
                p = c
            end do
        end if
        self%heap(p) = slot; self%pos(slot) = p
    end subroutine queue_set

    pure logical function earlier(ta, a, tb, b)
        real(dp), intent(in) :: ta, tb
        integer, intent(in) :: a, b
        earlier = ta < tb .or. (ta == tb .and. a < b)
    end function earlier

    !> The heap order holds and pos inverts heap (for tests).
    logical function queue_check(self) result(ok)
        class(event_queue_t), intent(in) :: self
        integer :: p
        ok = .true.
        do p = 1, self%n
            ok = ok .and. self%pos(self%heap(p)) == p
            if (p > 1) ok = ok .and. .not. earlier(self%t(self%heap(p)), self%heap(p), &
                                                   self%t(self%heap(p/2)), self%heap(p/2))
        end do
    end function queue_check

end module terrace_event_queue
