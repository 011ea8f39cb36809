!> Thermodynamic output: the CSV file (header `step,time,temp,pe,ke,etotal,press,px,py,pz,lx,ly,lz`, extensive totals
!> in the run's units, full precision) and the same lines on screen with the simulated time reached
!> and an estimate of the wall time to completion. Rank 0 writes; other ranks do nothing here.
!> Between screen lines further apart than progress_seconds of wall time (sparse samples, or none),
!> tick (called once per step or event) prints a progress line, so that a slow run shows it moves.
module terrace_thermo
    use terrace_kinds, only: dp, i8
    use terrace_mpi_env, only: world
    use terrace_observables, only: thermo_sample_t
    use terrace_units, only: units_t
    use terrace_errors, only: check_all
    use terrace_file_ops, only: temporary_name, remove_at_exit, path_kind, path_regular, check_size
    use mpi_f08, only: MPI_Wtime
    use, intrinsic :: iso_fortran_env, only: output_unit
    implicit none
    private

    ! the sample type lives with the observables (below the engine); named here too for old callers
    public :: thermo_sample_t

    type, public :: thermo_writer_t
        integer :: unit = -1
        logical :: to_file = .false.
        real(dp) :: wall_start = 0
        real(dp) :: end_time = 0
        integer(i8) :: end_step = 0          !< a run counted in steps or events only: its count (progress)
        character(len=:), allocatable :: time_unit
        character(len=:), allocatable :: extra_header
        integer(i8) :: lines = 0             !< samples written (CSV data lines, kept ones included)
        character(len=:), allocatable :: path  !< the CSV file; written as temporary_name(path) until the
                                               !< run succeeds (terrace_output_files: commit_small_outputs)
        logical :: failed = .false.          !< a write failed (full disk): reported by close, collectively
        integer(i8) :: bytes = 0             !< bytes written to the file (checked against its size at close)
        character(len=256) :: why = ''
        !> progress lines: wall seconds without a screen line before one is printed (0: none); the
        !> clock is read every `stride` ticks (at most 4: a tick may suddenly take long)
        real(dp) :: progress_seconds = 60
        real(dp) :: last_line = 0, last_read = 0
        integer(i8) :: ticks = 0, next_read = 1, stride = 1
    contains
        procedure :: open => thermo_open
        procedure :: open_append => thermo_open_append
        procedure, private :: start => thermo_start
        procedure, nopass :: check_append => thermo_check_append
        procedure :: write => thermo_write
        procedure :: tick => thermo_tick
        procedure :: close => thermo_close
        procedure :: discard => thermo_discard
    end type thermo_writer_t

contains

    !> Open the CSV (when a file name is given) and print the screen header.
    subroutine thermo_open(self, path, end_time, time_unit, extra_header, ok, msg, units, mesh)
        class(thermo_writer_t), intent(inout) :: self
        character(len=*), intent(in) :: path, time_unit, extra_header
        real(dp), intent(in) :: end_time
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        type(units_t), intent(in), optional :: units
        !> the atoms are a mesh's nodes: the screen says its temp column is no temperature of the solid
        logical, intent(in), optional :: mesh
        integer :: ios
        ok = .true.; msg = ''
        call self%start(end_time, time_unit, extra_header)
        if (world%rank /= 0) return
        if (len_trim(path) > 0) then
            self%path = path
            open (newunit=self%unit, file=temporary_name(path), status='replace', action='write', iostat=ios, &
                  iomsg=msg)
            if (ios /= 0) then
                ok = .false.
                return
            end if
            call remove_at_exit(temporary_name(path))
            self%to_file = .true.
            write (self%unit, '(a)', iostat=ios, iomsg=msg) 'step,time,temp,pe,ke,etotal,press,px,py,pz,lx,ly,lz'// &
                extra_header
            self%bytes = len('step,time,temp,pe,ke,etotal,press,px,py,pz,lx,ly,lz'//extra_header) + 1
            if (ios /= 0) then
                ok = .false.
                close (self%unit, status='delete')
                self%to_file = .false.
                return
            end if
        end if
        call screen_header(units, mesh)
    end subroutine thermo_open

    !> What thermo_open and thermo_open_append share: the run's end, the time unit, the extra
    !> columns' header and the wall clock's start (progress and the lines' pacing).
    subroutine thermo_start(self, end_time, time_unit, extra_header)
        class(thermo_writer_t), intent(inout) :: self
        real(dp), intent(in) :: end_time
        character(len=*), intent(in) :: time_unit, extra_header
        self%end_time = end_time
        self%time_unit = time_unit
        self%extra_header = extra_header
        self%wall_start = MPI_Wtime()
        self%last_line = self%wall_start; self%last_read = self%wall_start
    end subroutine thermo_start

    !> The screen's column names, with the units on a second line (and, for a mesh, what its temp
    !> column is: the nodes' kinetic energy per degree of freedom over k_B, whatever the units).
    subroutine screen_header(units, mesh)
        type(units_t), intent(in), optional :: units
        logical, intent(in), optional :: mesh
        write (output_unit, '(a10,1x,a12,1x,a12,1x,a16,1x,a16,1x,a16,1x,a13,a)') 'step', 'time', 'temp', 'pe', 'ke', &
            'etotal', 'press', '  progress'
        if (present(units)) write (output_unit, '(a)') '      (units: time '//trim(units%time)//', temp '// &
            trim(units%temperature)//', pe ke etotal '//trim(units%energy)//', press '//trim(units%pressure)// &
            '; progress: % of the run and wall seconds left)'
        if (present(mesh)) then
            if (mesh) write (output_unit, '(a)') "      (a mesh: temp is the nodes' kinetic energy per degree of "// &
                'freedom over k_B, not a temperature of the solid)'
        end if
    end subroutine screen_header

    !> Continue the CSV of an interrupted run (restart from a checkpoint): keep its header and its
    !> first `keep` data lines, drop any later ones (written after the checkpoint by a run that was
    !> then killed), and append. Fails when the file is missing or holds fewer lines.
    subroutine thermo_open_append(self, path, end_time, time_unit, extra_header, keep, ok, msg, units, mesh)
        class(thermo_writer_t), intent(inout) :: self
        character(len=*), intent(in) :: path, time_unit, extra_header
        real(dp), intent(in) :: end_time
        integer(i8), intent(in) :: keep
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        logical, intent(in), optional :: mesh     !< as in thermo_open
        type(units_t), intent(in), optional :: units
        character(len=:), allocatable :: text
        integer :: ios, pos
        ok = .true.; msg = ''
        call self%start(end_time, time_unit, extra_header)
        self%lines = keep
        if (world%rank /= 0) return
        if (len_trim(path) > 0) then
            self%path = path
            call read_kept_lines(path, keep, text, pos, ok, msg)
            if (.not. ok) return
            open (newunit=self%unit, file=temporary_name(path), access='stream', form='unformatted', &
                  status='replace', action='write', iostat=ios, iomsg=msg)
            if (ios /= 0) then
                ok = .false.; return
            end if
            write (self%unit, iostat=ios, iomsg=msg) text(1:pos)
            self%bytes = pos
            if (ios == 0) close (self%unit, iostat=ios, iomsg=msg)
            if (ios /= 0) then
                ok = .false.; return
            end if
            open (newunit=self%unit, file=temporary_name(path), status='old', position='append', action='write', &
                  iostat=ios, iomsg=msg)
            if (ios /= 0) then
                ok = .false.; return
            end if
            self%to_file = .true.
        end if
        call screen_header(units, mesh)
    end subroutine thermo_open_append

    !> Whether a restart can continue the thermo file `path` (rank 0; read only, nothing changed):
    !> it exists and holds the header and `keep` data lines. A restart checks every output so
    !> before it cuts any back.
    subroutine thermo_check_append(path, keep, ok, msg)
        character(len=*), intent(in) :: path
        integer(i8), intent(in) :: keep
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        character(len=:), allocatable :: text
        integer :: pos
        ok = .true.; msg = ''
        if (world%rank /= 0 .or. len_trim(path) == 0) return
        call read_kept_lines(path, keep, text, pos, ok, msg)
    end subroutine thermo_check_append

    !> The thermo file's text (its newest lines under the temporary name when a killed run left
    !> them there) and pos, the length of its header and first `keep` data lines.
    subroutine read_kept_lines(path, keep, text, pos, ok, msg)
        character(len=*), intent(in) :: path
        integer(i8), intent(in) :: keep
        character(len=:), allocatable, intent(out) :: text
        integer, intent(out) :: pos
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        character(len=:), allocatable :: source
        integer :: unit, ios, n, nl
        integer(i8) :: lines
        ok = .true.; msg = ''
        pos = 0
        source = path
        if (path_kind(temporary_name(path)) == path_regular) source = temporary_name(path)
        open (newunit=unit, file=source, access='stream', form='unformatted', status='old', action='read', &
              iostat=ios, iomsg=msg)
        if (ios /= 0) then
            ok = .false.; return
        end if
        inquire (unit=unit, size=n)
        allocate (character(len=max(n, 0)) :: text)
        if (n > 0) read (unit, iostat=ios) text
        close (unit)
        ! the header line and `keep` data lines
        lines = -1
        do while (lines < keep)
            nl = index(text(pos + 1:), new_line('a'))
            if (nl == 0) exit
            pos = pos + nl
            lines = lines + 1
        end do
        if (lines < keep) then
            ok = .false.
            write (msg, '(a,i0,a)') 'holds fewer than the ', keep, ' data lines the checkpoint recorded'
        end if
    end subroutine read_kept_lines

    subroutine thermo_write(self, s, extra)
        class(thermo_writer_t), intent(inout) :: self
        type(thermo_sample_t), intent(in) :: s
        real(dp), intent(in), optional :: extra(:)
        character(len=64) :: eta
        character(len=1024) :: line
        real(dp) :: elapsed, remaining
        integer :: k, ios, n
        self%lines = self%lines + 1        ! counted on every rank (the checkpoint records it)
        if (world%rank /= 0) return
        call summary_sample(s)
        if (self%to_file .and. .not. self%failed) then
            write (line, '(i0,12(",",es24.16e3))') s%step, s%time, s%temp, s%pe, s%ke, s%etotal, s%press, &
                s%momentum, s%angular
            n = len_trim(line)
            if (present(extra)) then
                do k = 1, size(extra)
                    write (line(n + 1:), '(",",es24.16e3)') extra(k)
                    n = len_trim(line)
                end do
            end if
            write (self%unit, '(a)', iostat=ios, iomsg=self%why) line(1:n)
            self%bytes = self%bytes + n + 1
            if (ios == 0) flush (self%unit, iostat=ios, iomsg=self%why)
            self%failed = ios /= 0
        end if
        self%last_line = MPI_Wtime()
        eta = progress_text(self, s%step, s%time)
        write (output_unit, '(i10,1x,es12.5,1x,es12.5,1x,es16.9,1x,es16.9,1x,es16.9,1x,es13.5,a)') s%step, s%time, &
            s%temp, s%pe, s%ke, s%etotal, s%press, trim(eta)
        flush (output_unit)
    end subroutine thermo_write

    !> '  12.3%  eta    456.7 s': the share of the run (of its time, or of its steps or events when it
    !> is counted in those) and the wall time left; blank at the start.
    function progress_text(self, step, time) result(eta)
        class(thermo_writer_t), intent(in) :: self
        integer(i8), intent(in) :: step
        real(dp), intent(in) :: time
        character(len=64) :: eta
        real(dp) :: remaining
        real(dp) :: done
        eta = ''
        done = 0
        if (self%end_time > 0) then
            done = time/self%end_time
        else if (self%end_step > 0) then
            done = real(step, dp)/self%end_step
        end if
        if (done > 0) then
            remaining = (self%last_line - self%wall_start)*(1 - done)/done
            write (eta, '(a,f6.1,a,f9.1,a)') '  ', 100*done, '%  eta ', remaining, ' s'
        end if
    end function progress_text

    !> One step (velocity Verlet) or event (energy stepping, event-driven) done: on rank 0, a progress
    !> line when no screen line has been printed for progress_seconds of wall time. No communication.
    subroutine thermo_tick(self, step, time)
        class(thermo_writer_t), intent(inout) :: self
        integer(i8), intent(in) :: step
        real(dp), intent(in) :: time
        real(dp) :: now
        character(len=24) :: t
        self%ticks = self%ticks + 1
        if (self%ticks < self%next_read) return
        if (world%rank /= 0 .or. .not. self%progress_seconds > 0) then
            self%next_read = huge(self%next_read)
            return
        end if
        now = MPI_Wtime()
        if (now - self%last_read < 0.05_dp) then
            self%stride = min(2*self%stride, 4_i8)
        else if (now - self%last_read > 0.5_dp) then
            self%stride = max(self%stride/2, 1_i8)
        end if
        self%last_read = now
        self%next_read = self%ticks + self%stride
        if (now - self%last_line < self%progress_seconds) return
        self%last_line = now
        write (t, '(es12.5)') time
        write (output_unit, '(a,i0,a)') '  progress: step ', step, ', time '//trim(adjustl(t))//' '// &
            self%time_unit//trim(progress_text(self, step, time))
        flush (output_unit)
    end subroutine thermo_tick

    !> The last thermo sample, in the run summary (thermo_last).
    subroutine summary_sample(s)
        use terrace_run_summary, only: summary_put
        type(thermo_sample_t), intent(in) :: s
        call summary_put('thermo_last/step', s%step)
        call summary_put('thermo_last/', [character(len=6) :: 'time', 'temp', 'pe', 'ke', 'etotal', 'press'], &
                         [s%time, s%temp, s%pe, s%ke, s%etotal, s%press])
    end subroutine summary_sample

    !> Close and delete the CSV (a run that stops before its first step leaves no file).
    subroutine thermo_discard(self)
        class(thermo_writer_t), intent(inout) :: self
        if (self%to_file) close (self%unit, status='delete')
        self%to_file = .false.
    end subroutine thermo_discard

    !> Close the file and stop every rank if any write or the close failed (a full disk): the
    !> previous file at the path is then untouched (the temporary file is removed at exit).
    !> Collective.
    subroutine thermo_close(self)
        class(thermo_writer_t), intent(inout) :: self
        integer :: ios
        logical :: ok
        if (self%to_file) then
            if (.not. self%failed) then
                close (self%unit, iostat=ios, iomsg=self%why)
                self%failed = ios /= 0
                if (.not. self%failed) call check_size(temporary_name(self%path), self%bytes, ok, self%why)
                if (.not. self%failed) self%failed = .not. ok
            else
                close (self%unit, iostat=ios)
            end if
        end if
        self%to_file = .false.
        if (.not. allocated(self%path)) self%path = ''
        call check_all(.not. self%failed, self%path//': &output: thermo_file: cannot write: '//trim(self%why))
    end subroutine thermo_close

end module terrace_thermo
