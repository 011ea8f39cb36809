!> The configuration of terrace-analyze: the namelist group &analysis (from a file, from
!> command-line flags, or both: flags override the file), read with Terrace's own namelist
!> tokeniser so that every error names the file (or the command line), line, group and key.
!>
!>   terrace-analyze ANALYSIS.nml
!>   terrace-analyze --trajectory_file=run.h5 --compute=vdos,rdf [--KEY=VALUE ...]
!>   terrace-analyze ANALYSIS.nml --first_frame=101
!>
!> Keys and defaults: doc/analysis.md. Times are in the trajectory's time unit, lengths in its
!> length unit, frames are numbered from 1 (first_frame) and -1 is the last (last_frame).
module terrace_analysis_config
    use terrace_kinds, only: dp, i8
    use terrace_namelist_text, only: namelist_file_t, parse_namelist_text, lower, at_line
    use terrace_errors, only: stop_all
    use terrace_files, only: read_input_text
    implicit none
    private

    real(dp), parameter :: unset = -huge(1.0_dp)

    type, public :: analysis_config_t
        character(len=:), allocatable :: path            !< the namelist file ('' when flags only)
        type(namelist_file_t) :: file_nml, flag_nml
        character(len=512) :: trajectory_file = ''
        character(len=64) :: particles_group = 'all'
        character(len=512) :: output_prefix = 'analysis'
        character(len=128) :: compute = ''
        logical :: vdos = .false., rdf = .false., msd = .false., sq = .false.
        integer(i8) :: first_frame = 1, last_frame = -1, frame_stride = 1
        ! VACF / VDOS
        real(dp) :: correlation_time = unset           !< longest VACF lag (time); default: half the span
        character(len=16) :: window = 'hann'
        integer :: zero_padding = 4
        ! g(r)
        real(dp) :: rdf_r_max = unset
        integer :: rdf_bins = 200
        integer(i8) :: rdf_every = 1
        ! MSD and diffusion
        real(dp) :: msd_max_time = unset
        real(dp) :: msd_fit_start = unset, msd_fit_end = unset
        integer :: msd_blocks = 5
        ! S(q)
        real(dp) :: sq_q_max = unset
        real(dp) :: sq_bin_width = unset
        integer(i8) :: sq_every = 1
    contains
        procedure :: where => cfg_where
        procedure :: given => cfg_given
    end type analysis_config_t

    public :: read_analysis_config, is_unset, frame_window

    integer(i8), parameter, public :: batch_values = 4194304   !< positions an analysis reads at once (32 MiB)

    !> The frames an analysis reads: first (0-based), how many, every stride-th; its plans extend it.
    type, public :: frame_plan_t
        integer(i8) :: f0 = 0, nsel = 0, stride = 1
    end type frame_plan_t

    character(len=*), parameter :: keys(21) = [character(len=72) :: &
        'trajectory_file:s:a quoted file name', 'particles_group:s:a quoted group name', &
        'output_prefix:s:a quoted path prefix', 'compute:s:a quoted list of vdos, rdf, msd, sq', &
        'first_frame:i:an integer (1 = first frame)', 'last_frame:i:an integer (-1 = last frame)', &
        'frame_stride:i:an integer', 'correlation_time:r:a real number (time)', &
        'window:s:a quoted string', 'zero_padding:i:an integer', 'rdf_r_max:r:a real number (length)', &
        'rdf_bins:i:an integer', 'rdf_every:i:an integer', 'msd_max_time:r:a real number (time)', &
        'msd_fit_start:r:a real number (time)', 'msd_fit_end:r:a real number (time)', &
        'msd_blocks:i:an integer', 'sq_q_max:r:a real number (inverse length)', &
        'sq_bin_width:r:a real number (inverse length)', 'sq_every:i:an integer', &
        'help:x:-']

contains

    elemental logical function is_unset(x)
        real(dp), intent(in) :: x
        is_unset = x == unset
    end function is_unset

    !> "file:line: &analysis: key" of the assignment in force (flags win over the file).
    function cfg_where(self, key) result(s)
        class(analysis_config_t), intent(in) :: self
        character(len=*), intent(in) :: key
        character(len=:), allocatable :: s
        if (self%flag_nml%find('analysis', key) > 0) then
            s = '(command line): &analysis: '//key
        else if (allocated(self%file_nml%path)) then
            s = self%file_nml%where('analysis', key)
        else
            s = '(command line): &analysis: '//key
        end if
    end function cfg_where

    logical function cfg_given(self, key)
        class(analysis_config_t), intent(in) :: self
        character(len=*), intent(in) :: key
        cfg_given = self%flag_nml%find('analysis', key) > 0
        if (allocated(self%file_nml%path)) cfg_given = cfg_given .or. self%file_nml%find('analysis', key) > 0
    end function cfg_given

    !> Read the namelist file `path` ('' for none) and the flags (--key=value or --key value;
    !> list values may use commas or blanks); collective; every error stops every rank.
    subroutine read_analysis_config(path, flags, cfg)
        character(len=*), intent(in) :: path
        character(len=*), intent(in) :: flags(:)
        type(analysis_config_t), intent(out) :: cfg
        character(len=:), allocatable :: text, flag_text

        cfg%path = trim(path)
        if (len_trim(path) > 0) then
            call read_input_text(trim(path), text)
            call parse_namelist_text(text, trim(path), cfg%file_nml)
            if (len(cfg%file_nml%syntax_error) > 0) call stop_all(cfg%file_nml%syntax_error)
            call check_groups(cfg%file_nml)
            if (.not. cfg%file_nml%has_group('analysis')) call stop_all(trim(path)// &
                ': &analysis: missing (the analysis is set by the namelist group &analysis ... /)')
        end if
        flag_text = flags_to_namelist(flags)
        call parse_namelist_text(flag_text, '(command line)', cfg%flag_nml)
        if (len(cfg%flag_nml%syntax_error) > 0) call stop_all(cfg%flag_nml%syntax_error)

        if (len_trim(path) > 0) call read_items(cfg, cfg%file_nml)
        call read_items(cfg, cfg%flag_nml)
        call validate(cfg)
    end subroutine read_analysis_config

    subroutine check_groups(nf)
        type(namelist_file_t), intent(in) :: nf
        integer :: i
        character(len=16) :: ln
        do i = 1, nf%ngroups
            write (ln, '(i0)') nf%group_lines(i)
            if (nf%groups(i) /= 'analysis') call stop_all(nf%path//':'//trim(ln)//': &'//trim(nf%groups(i))// &
                                                          ': unknown namelist group (allowed: analysis)')
            if (count(nf%groups(1:i - 1) == 'analysis') > 0) call stop_all(nf%path//':'//trim(ln)// &
                ': &analysis: group given twice (merge its keys into one group)')
        end do
    end subroutine check_groups

    !> "--key=value --key value ..." as one &analysis group; string keys are quoted.
    function flags_to_namelist(flags) result(text)
        character(len=*), intent(in) :: flags(:)
        character(len=:), allocatable :: text
        character(len=:), allocatable :: key, value
        integer :: i, p, k
        character :: kind
        text = '&analysis '
        i = 1
        do while (i <= size(flags))
            if (flags(i)(1:2) /= '--') call stop_all("(command line): '"//trim(flags(i))// &
                "': expected --key=value (see terrace-analyze --help)", 2)
            p = index(flags(i), '=')
            if (p > 0) then
                key = lower(flags(i)(3:p - 1)); value = trim(flags(i)(p + 1:))
            else
                key = lower(trim(flags(i)(3:)))
                if (i == size(flags)) call stop_all('(command line): --'//key//': no value (expected --'//key// &
                                                    '=VALUE)', 2)
                i = i + 1
                value = trim(flags(i))
            end if
            kind = ' '
            do k = 1, size(keys)
                if (keys(k)(1:index(keys(k), ':') - 1) == key) kind = keys(k)(index(keys(k), ':') + 1:index(keys(k), ':') + 1)
            end do
            if (kind == ' ' .or. kind == 'x') call stop_all('(command line): --'//key//': unknown option (allowed: '// &
                                                            'the &analysis keys, see terrace-analyze --help)', 2)
            if (kind == 's') then
                if (index(value, "'") > 0) call stop_all('(command line): --'//key//": the value may not contain '", 2)
                value = "'"//value//"'"
            end if
            text = text//' '//key//' = '//value//','
            i = i + 1
        end do
        text = text//' /'
    end function flags_to_namelist

    subroutine read_items(cfg, nf)
        type(analysis_config_t), intent(inout) :: cfg
        type(namelist_file_t), intent(in) :: nf
        character(len=512) :: trajectory_file, output_prefix
        character(len=64) :: particles_group
        character(len=128) :: compute
        character(len=16) :: window
        integer(i8) :: first_frame, last_frame, frame_stride, rdf_every, sq_every
        integer :: zero_padding, rdf_bins, msd_blocks
        real(dp) :: correlation_time, rdf_r_max, msd_max_time, msd_fit_start, msd_fit_end, sq_q_max, sq_bin_width
        namelist /analysis/ trajectory_file, particles_group, output_prefix, compute, first_frame, last_frame, &
            frame_stride, correlation_time, window, zero_padding, rdf_r_max, rdf_bins, rdf_every, msd_max_time, &
            msd_fit_start, msd_fit_end, msd_blocks, sq_q_max, sq_bin_width, sq_every
        character(len=256) :: msg
        character(len=:), allocatable :: buf, kind, names
        integer :: k, i, p, ios
        logical :: known
        trajectory_file = cfg%trajectory_file; output_prefix = cfg%output_prefix
        particles_group = cfg%particles_group; compute = cfg%compute; window = cfg%window
        first_frame = cfg%first_frame; last_frame = cfg%last_frame; frame_stride = cfg%frame_stride
        rdf_every = cfg%rdf_every; sq_every = cfg%sq_every; zero_padding = cfg%zero_padding
        rdf_bins = cfg%rdf_bins; msd_blocks = cfg%msd_blocks; correlation_time = cfg%correlation_time
        rdf_r_max = cfg%rdf_r_max; msd_max_time = cfg%msd_max_time; msd_fit_start = cfg%msd_fit_start
        msd_fit_end = cfg%msd_fit_end; sq_q_max = cfg%sq_q_max; sq_bin_width = cfg%sq_bin_width
        do k = 1, nf%count
            known = .false.
            do i = 1, size(keys) - 1
                p = index(keys(i), ':')
                if (keys(i)(1:p - 1) == nf%items(k)%key) then
                    known = .true.; kind = trim(keys(i)(p + 3:))
                end if
            end do
            if (.not. known) then
                names = ''
                do i = 1, size(keys) - 1
                    names = names//keys(i)(1:index(keys(i), ':') - 1)
                    if (i < size(keys) - 1) names = names//', '
                end do
                call stop_all(at_line(nf%path, nf%items(k)%line)//'&analysis: '//trim(nf%items(k)%key)//': unknown key (allowed: '// &
                              names//')')
            end if
            buf = '&analysis '//nf%items(k)%target//' = '//nf%items(k)%value//' /'
            read (buf, nml=analysis, iostat=ios, iomsg=msg)
            if (ios /= 0) call stop_all(at_line(nf%path, nf%items(k)%line)//'&analysis: '//nf%items(k)%target//' = '// &
                                        nf%items(k)%value//': cannot read the value (expected '//kind//'; '// &
                                        trim(msg)//')')
        end do
        cfg%trajectory_file = trajectory_file; cfg%output_prefix = output_prefix
        cfg%particles_group = particles_group; cfg%compute = lower(compute); cfg%window = lower(window)
        cfg%first_frame = first_frame; cfg%last_frame = last_frame; cfg%frame_stride = frame_stride
        cfg%rdf_every = rdf_every; cfg%sq_every = sq_every; cfg%zero_padding = zero_padding
        cfg%rdf_bins = rdf_bins; cfg%msd_blocks = msd_blocks; cfg%correlation_time = correlation_time
        cfg%rdf_r_max = rdf_r_max; cfg%msd_max_time = msd_max_time; cfg%msd_fit_start = msd_fit_start
        cfg%msd_fit_end = msd_fit_end; cfg%sq_q_max = sq_q_max; cfg%sq_bin_width = sq_bin_width
    end subroutine read_items


    !> Checks that need no trajectory (those against the file's frames are made once it is open).
    subroutine validate(cfg)
        type(analysis_config_t), intent(inout) :: cfg
        character(len=32) :: word
        character(len=128) :: list
        character(len=:), allocatable :: source
        integer :: i
        if (len_trim(cfg%path) > 0) then
            source = cfg%path
        else
            source = '(command line)'
        end if
        if (len_trim(cfg%trajectory_file) == 0) call stop_all(source//': &analysis: trajectory_file: missing '// &
                                                              '(the H5MD file to analyse)')
        list = cfg%compute
        do i = 1, len_trim(list)
            if (list(i:i) == ',') list(i:i) = ' '
        end do
        if (len_trim(list) == 0) call stop_all(source//": &analysis: compute: missing (a list of 'vdos', 'rdf', "// &
                                               "'msd', 'sq')")
        do
            list = adjustl(list)
            if (len_trim(list) == 0) exit
            i = index(list, ' ')
            word = list(1:i - 1)
            list = list(i:)
            select case (trim(word))
            case ('vdos', 'vacf')
                cfg%vdos = .true.
            case ('rdf', 'gr')
                cfg%rdf = .true.
            case ('msd', 'diffusion')
                cfg%msd = .true.
            case ('sq', 'structure_factor')
                cfg%sq = .true.
            case default
                call stop_all(cfg%where('compute')//": unknown analysis '"//trim(word)// &
                              "' (allowed: 'vdos', 'rdf', 'msd', 'sq')")
            end select
        end do
        if (cfg%first_frame < 1) call stop_all(cfg%where('first_frame')//': must be >= 1 (1 is the first frame)')
        if (cfg%last_frame == 0 .or. cfg%last_frame < -1) call stop_all(cfg%where('last_frame')// &
            ': must be a frame number >= 1, or -1 for the last frame')
        if (cfg%frame_stride < 1) call stop_all(cfg%where('frame_stride')//': must be >= 1')
        if (cfg%rdf_every < 1) call stop_all(cfg%where('rdf_every')//': must be >= 1')
        if (cfg%sq_every < 1) call stop_all(cfg%where('sq_every')//': must be >= 1')
        select case (trim(cfg%window))
        case ('hann', 'blackman', 'none')
        case default
            call stop_all(cfg%where('window')//" = '"//trim(cfg%window)//"': unknown window (allowed: 'hann', "// &
                          "'blackman', 'none')")
        end select
        if (cfg%zero_padding < 1 .or. cfg%zero_padding > 64) call stop_all(cfg%where('zero_padding')// &
            ': must be 1..64 (factor by which the correlation is padded with zeros before its transform)')
        if (cfg%given('correlation_time') .and. .not. (cfg%correlation_time > 0)) &
            call stop_all(cfg%where('correlation_time')//': must be > 0 (a time)')
        if (cfg%given('rdf_r_max') .and. .not. (cfg%rdf_r_max > 0)) call stop_all(cfg%where('rdf_r_max')// &
            ': must be > 0 (a length)')
        if (cfg%rdf_bins < 1 .or. cfg%rdf_bins > 10000000) call stop_all(cfg%where('rdf_bins')// &
            ': must be between 1 and 10000000 (a histogram of that many bins is finer than any trajectory resolves)')
        if (cfg%given('msd_max_time') .and. .not. (cfg%msd_max_time > 0)) call stop_all(cfg%where('msd_max_time')// &
            ': must be > 0 (a time)')
        if (cfg%given('msd_fit_start') .and. .not. (cfg%msd_fit_start >= 0)) call stop_all(cfg%where('msd_fit_start')// &
            ': must be >= 0 (a time)')
        if (cfg%given('msd_fit_end') .and. .not. (cfg%msd_fit_end > 0)) call stop_all(cfg%where('msd_fit_end')// &
            ': must be > 0 (a time)')
        if (cfg%given('msd_fit_start') .and. cfg%given('msd_fit_end')) then
            if (.not. (cfg%msd_fit_end > cfg%msd_fit_start)) call stop_all(cfg%where('msd_fit_end')// &
                ': must be > msd_fit_start')
        end if
        if (cfg%msd_blocks < 2) call stop_all(cfg%where('msd_blocks')//': must be >= 2 (the error bar comes from '// &
                                              'the spread of the block estimates)')
        if (cfg%given('sq_q_max') .and. .not. (cfg%sq_q_max > 0)) call stop_all(cfg%where('sq_q_max')// &
            ': must be > 0 (an inverse length)')
        if (cfg%given('sq_bin_width') .and. .not. (cfg%sq_bin_width > 0)) call stop_all(cfg%where('sq_bin_width')// &
            ': must be > 0 (an inverse length)')
    end subroutine validate

    !> The frames selected by first_frame, last_frame and frame_stride * extra_stride from an element
    !> of nframes frames (`element` names it in messages): f0 (0-based), nsel frames, stride.
    subroutine frame_window(cfg, nframes, element, extra_stride, plan)
        class(analysis_config_t), intent(in) :: cfg
        integer(i8), intent(in) :: nframes, extra_stride
        character(len=*), intent(in) :: element
        class(frame_plan_t), intent(inout) :: plan
        integer(i8) :: last
        character(len=32) :: a, b
        write (b, '(i0)') nframes
        if (nframes < 1) call stop_all(element//': no frames')
        if (cfg%first_frame > nframes) then
            write (a, '(i0)') cfg%first_frame
            call stop_all(cfg%where('first_frame')//' = '//trim(a)//': beyond the last frame of '//element// &
                          ' ('//trim(b)//' frames)')
        end if
        last = cfg%last_frame
        if (last == -1) last = nframes
        if (last > nframes) then
            write (a, '(i0)') cfg%last_frame
            call stop_all(cfg%where('last_frame')//' = '//trim(a)//': beyond the last frame of '//element// &
                          ' ('//trim(b)//' frames)')
        end if
        if (last < cfg%first_frame) call stop_all(cfg%where('last_frame')//': before first_frame')
        plan%stride = cfg%frame_stride*extra_stride
        plan%f0 = cfg%first_frame - 1
        plan%nsel = (last - cfg%first_frame)/plan%stride + 1
    end subroutine frame_window

end module terrace_analysis_config
