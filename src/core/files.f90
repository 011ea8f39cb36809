!> What the operating system gives the program: the whole contents of a text file, and this
!> process's peak resident memory.
!>
!> peak_memory_kib reads VmHWM ("high water mark" of the resident set, in KiB) from
!> /proc/self/status; it is 0 where /proc is not available.
module terrace_files
    use terrace_kinds, only: i8
    implicit none
    private

    public :: slurp, peak_memory_kib

contains

    !> The whole file `path` as one string (line ends kept); status /= 0 when it cannot be read.
    subroutine slurp(path, text, status)
        character(len=*), intent(in) :: path
        character(len=:), allocatable, intent(out) :: text
        integer, intent(out) :: status
        integer :: unit, n
        open (newunit=unit, file=path, access='stream', form='unformatted', status='old', &
              action='read', iostat=status)
        if (status /= 0) return
        inquire (unit=unit, size=n)
        allocate (character(len=max(n, 0)) :: text)
        if (n > 0) read (unit, iostat=status) text
        close (unit)
    end subroutine slurp

    !> VmHWM of this process in KiB (0 when /proc is not available).
    integer(i8) function peak_memory_kib() result(kib)
        integer :: unit, ios
        character(len=256) :: line
        kib = 0
        open (newunit=unit, file='/proc/self/status', action='read', status='old', iostat=ios)
        if (ios /= 0) return
        do
            read (unit, '(a)', iostat=ios) line
            if (ios /= 0) exit
            if (line(1:6) == 'VmHWM:') then
                read (line(7:), *, iostat=ios) kib
                exit
            end if
        end do
        close (unit)
    end function peak_memory_kib

end module terrace_files
