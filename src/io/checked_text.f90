!> A small text output written under a temporary name and checked line by line: gfortran does
!> not report a full disk on write, flush or close, so the bytes written are counted and compared
!> with the closed file's size. The file is renamed over its real name only when the run succeeds
!> (terrace_output_files: commit_small_outputs); a failed or short file is removed at exit.
module terrace_checked_text
    use terrace_kinds, only: dp, i8
    use terrace_file_ops, only: temporary_name, remove_at_exit, check_size
    implicit none
    private
    public :: write_table

    type, public :: checked_text_t
        integer :: unit = -1, ios = 0
        integer(i8) :: bytes = 0
        character(len=:), allocatable :: tmp
    contains
        procedure :: open => checked_open
        procedure :: put => checked_put
        procedure :: put_rows => checked_put_rows
        procedure :: close => checked_close
    end type checked_text_t

contains

    subroutine checked_open(self, path, ok, msg)
        class(checked_text_t), intent(inout) :: self
        character(len=*), intent(in) :: path
        logical, intent(out) :: ok
        character(len=*), intent(inout) :: msg
        self%tmp = temporary_name(path)
        self%bytes = 0
        open (newunit=self%unit, file=self%tmp, status='replace', action='write', iostat=self%ios, iomsg=msg)
        ok = self%ios == 0
        if (ok) call remove_at_exit(self%tmp)
    end subroutine checked_open

    !> One line (trailing blanks dropped); nothing more after the first failure.
    subroutine checked_put(self, text, msg)
        class(checked_text_t), intent(inout) :: self
        character(len=*), intent(in) :: text
        character(len=*), intent(inout) :: msg
        if (self%ios /= 0) return
        write (self%unit, '(a)', iostat=self%ios, iomsg=msg) trim(text)
        self%bytes = self%bytes + len_trim(text) + 1
    end subroutine checked_put

    !> One line per column i of v: 'k(i) v(1, i) v(2, i) ...', reals in full precision.
    subroutine checked_put_rows(self, k, v, msg)
        class(checked_text_t), intent(inout) :: self
        integer(i8), intent(in) :: k(:)
        real(dp), intent(in) :: v(:, :)
        character(len=*), intent(inout) :: msg
        character(len=32) :: fmt
        character(len=40*(size(v, 1) + 1)) :: line
        integer :: i
        write (fmt, '(a,i0,a)') '(i0,', size(v, 1), '(1x,es24.16e3))'
        do i = 1, size(k)
            if (self%ios /= 0) exit
            write (line, fmt) k(i), v(:, i)
            call self%put(line, msg)
        end do
    end subroutine checked_put_rows

    !> A whole small table: the header lines, then put_rows(k, v); written under a temporary name
    !> that terrace_output_files renames over path when the run succeeds, every write checked.
    subroutine write_table(path, header, k, v, ok, msg)
        character(len=*), intent(in) :: path, header(:)
        integer(i8), intent(in) :: k(:)
        real(dp), intent(in) :: v(:, :)
        logical, intent(out) :: ok
        character(len=*), intent(inout) :: msg
        type(checked_text_t) :: out
        integer :: i
        call out%open(path, ok, msg)
        if (.not. ok) return
        do i = 1, size(header)
            call out%put(header(i), msg)
        end do
        call out%put_rows(k, v, msg)
        call out%close(ok, msg)
    end subroutine write_table

    !> Close; ok when every line was written and the file holds all of them.
    subroutine checked_close(self, ok, msg)
        class(checked_text_t), intent(inout) :: self
        logical, intent(out) :: ok
        character(len=*), intent(inout) :: msg
        integer :: k
        if (self%ios == 0) then
            close (self%unit, iostat=self%ios, iomsg=msg)
            if (self%ios == 0) call check_size(self%tmp, self%bytes, ok, msg)
            if (self%ios == 0 .and. .not. ok) self%ios = -1
        else
            close (self%unit, status='delete', iostat=k)
        end if
        ok = self%ios == 0
    end subroutine checked_close

end module terrace_checked_text
