!> Gmsh MSH meshes (ASCII 4.1 and 2.2, as gmsh and meshio write them): nodes (tags are the atom
!> ids) and 4-node tetrahedra (element type 4) with the body each belongs to: its physical volume
!> tag. In MSH 4.1 a tetrahedron's volume entity is mapped to its physical tag through the
!> $Entities section (several entities in one physical volume are one body; a file without
!> $Entities takes the entity tag); in MSH 2.2 the first element tag is the physical tag. A mesh
!> without physical volumes (tag 0, or no physical tag on any volume entity) is one body, 1.
!> Each tetrahedron also keeps its volume entity's tag (Gmsh's elementary tag: the 4.1 block's
!> entity, the second tag in 2.2; 0 where a 2.2 line has none): the regions of a body that may have
!> materials of their own.
!> Points, lines and triangles (types 15, 1, 2: physical points, curves and surfaces) are skipped;
!> any other element type is refused. Every count the file declares is bounded by the file's size
!> before anything is allocated; a second $Nodes or $Elements section, a tetrahedron that repeats
!> a node, and coordinates beyond 1e9 are refused. Errors name the file and line.
module terrace_gmsh_mesh
    use terrace_kinds, only: dp, i8
    use terrace_text, only: int_text, count_tokens
    implicit none
    private

    type, public :: mesh_t
        integer :: nnode = 0, ntet = 0
        integer(i8), allocatable :: node_tag(:)     !< (nnode)
        real(dp), allocatable :: x(:, :)            !< (3, nnode) reference positions
        integer(i8), allocatable :: tet(:, :)       !< (4, ntet) node tags
        integer, allocatable :: body(:)             !< (ntet) physical volume tag (1 if none)
        integer, allocatable :: volume(:)           !< (ntet) volume entity (elementary) tag (0 if none)
        logical :: ok = .true.
        character(len=1024) :: error = ''
    end type mesh_t

    public :: read_gmsh

    real(dp), parameter :: max_coordinate = 1.0e9_dp

    !> The state of one read: the open file, the line reached, the format and what has been read.
    type :: gmsh_reader_t
        character(len=:), allocatable :: path
        integer :: u = -1, ios = 0, line_no = 0
        integer(i8) :: fsize = 0                     !< the file's size in bytes (bounds every count)
        real(dp) :: version = 0
        integer :: nodes_line = 0, elements_line = 0, entities_line = 0   !< where each section starts
        integer, allocatable :: tet_line(:)          !< (ntet) line of each tetrahedron
        integer(i8), allocatable :: vol_tag(:)       !< MSH 4.1 volume entities: tag,
        integer(i8), allocatable :: vol_phys(:)      !< first physical tag (0: none),
        integer, allocatable :: vol_nphys(:)         !< number of physical tags
        type(mesh_t) :: mesh
    end type gmsh_reader_t

    abstract interface
        !> One step of a read with a procedure for each format (a section's body, the bodies).
        subroutine read_step(r)
            import :: gmsh_reader_t
            type(gmsh_reader_t), intent(inout) :: r
        end subroutine read_step
    end interface

contains

    subroutine read_gmsh(path, mesh)
        character(len=*), intent(in) :: path
        type(mesh_t), intent(out) :: mesh
        type(gmsh_reader_t) :: r
        r%path = path
        inquire (file=path, size=r%fsize)
        open (newunit=r%u, file=path, status='old', action='read', iostat=r%ios)
        if (r%ios /= 0) then
            call fail(r, 0, 'cannot open the mesh file')
        else
            call read_format(r)
            if (r%mesh%ok) call read_sections(r)
            close (r%u)
        end if
        if (r%mesh%ok .and. r%mesh%nnode == 0) call fail(r, r%line_no, 'no $Nodes section')
        if (r%mesh%ok .and. r%mesh%ntet == 0) call fail(r, r%line_no, 'no tetrahedra (element type 4) in the mesh')
        if (r%mesh%ok) then
            ! room was made for every element the header declared; keep the tetrahedra only
            r%mesh%tet = r%mesh%tet(:, 1:r%mesh%ntet)
            r%mesh%body = r%mesh%body(1:r%mesh%ntet)
            r%mesh%volume = r%mesh%volume(1:r%mesh%ntet)
            call assign_bodies(r)
        end if
        if (r%mesh%ok) call check_nodes(r)
        call take_mesh(r%mesh, mesh)
    end subroutine read_gmsh

    !> The mesh read, handed over without copying its arrays.
    subroutine take_mesh(from, to)
        type(mesh_t), intent(inout) :: from
        type(mesh_t), intent(out) :: to
        to%nnode = from%nnode; to%ntet = from%ntet
        to%ok = from%ok; to%error = from%error
        if (allocated(from%node_tag)) call move_alloc(from%node_tag, to%node_tag)
        if (allocated(from%x)) call move_alloc(from%x, to%x)
        if (allocated(from%tet)) call move_alloc(from%tet, to%tet)
        if (allocated(from%body)) call move_alloc(from%body, to%body)
        if (allocated(from%volume)) call move_alloc(from%volume, to%volume)
    end subroutine take_mesh

    !> The first two lines: $MeshFormat, then "version file-type data-size" (ASCII 4.1 or 2.2).
    subroutine read_format(r)
        type(gmsh_reader_t), intent(inout) :: r
        character(len=4096) :: line
        integer :: ftype, dsize
        call next_line(r, line)
        if (r%ios /= 0 .or. trim(line) /= '$MeshFormat') then
            call fail(r, r%line_no, 'not a Gmsh MSH file (expected $MeshFormat on the first line)')
            return
        end if
        call next_line(r, line)
        read (line, *, iostat=r%ios) r%version, ftype, dsize
        if (r%ios /= 0) then
            call fail(r, r%line_no, 'bad $MeshFormat line (expected: version file-type data-size)')
        else if (ftype /= 0) then
            call fail(r, r%line_no, 'binary MSH files are not read: write ASCII (gmsh -format msh41 or -format msh22, '// &
                      'or meshio with binary=False)')
        else if (abs(r%version - 4.1_dp) > 1.0e-6_dp .and. abs(r%version - 2.2_dp) > 1.0e-6_dp) then
            call fail(r, r%line_no, 'unsupported MSH version (allowed: 4.1, 2.2)')
        end if
    end subroutine read_format

    !> The sections after the format, to the end of the file or the first failure: $Entities (4.1),
    !> $Nodes and $Elements, each at most once; any other section is passed over line by line.
    subroutine read_sections(r)
        type(gmsh_reader_t), intent(inout) :: r
        character(len=4096) :: line
        do
            call next_line(r, line)
            if (r%ios /= 0) exit
            select case (trim(line))
            case ('$Entities')
                if (r%version > 3) then
                    if (first_section(r, r%entities_line, '$Entities')) call entities41(r)
                end if
            case ('$Nodes')
                if (first_section(r, r%nodes_line, '$Nodes')) call by_version(r, nodes41, nodes22)
            case ('$Elements')
                if (first_section(r, r%elements_line, '$Elements')) call by_version(r, elements41, elements22)
            end select
            if (.not. r%mesh%ok) exit
        end do
    end subroutine read_sections

    !> A step of the read done by the procedure of the file's format: v41 (MSH 4.1) or v22 (MSH 2.2).
    subroutine by_version(r, v41, v22)
        type(gmsh_reader_t), intent(inout) :: r
        procedure(read_step) :: v41, v22
        if (r%version > 3) then
            call v41(r)
        else
            call v22(r)
        end if
    end subroutine by_version

    !> A section that may appear once: its line is kept (first_line), or a second one is a failure.
    logical function first_section(r, first_line, name) result(first)
        type(gmsh_reader_t), intent(inout) :: r
        integer, intent(inout) :: first_line
        character(len=*), intent(in) :: name
        first = first_line == 0
        if (first) then
            first_line = r%line_no
        else
            call fail(r, r%line_no, 'a second '//name//' section (the first is at line '//int_text(first_line)// &
                      '; a mesh file has one)')
        end if
    end function first_section

    subroutine next_line(r, text)
        type(gmsh_reader_t), intent(inout) :: r
        character(len=*), intent(out) :: text
        read (r%u, '(a)', iostat=r%ios) text
        if (r%ios == 0) r%line_no = r%line_no + 1
    end subroutine next_line

    subroutine fail(r, at, what)
        type(gmsh_reader_t), intent(inout) :: r
        integer, intent(in) :: at
        character(len=*), intent(in) :: what
        r%mesh%ok = .false.
        if (at > 0) then
            r%mesh%error = r%path//':'//int_text(at)//': &system: mesh_file: '//what
        else
            r%mesh%error = r%path//': &system: mesh_file: '//what
        end if
    end subroutine fail

    !> A count the file declares (what: '$Nodes declares %n nodes') is at most what a file of
    !> fsize bytes can hold at min_bytes bytes per item; else a failure naming the line.
    logical function count_fits(r, n, min_bytes, what) result(ok)
        type(gmsh_reader_t), intent(inout) :: r
        integer(i8), intent(in) :: n
        integer, intent(in) :: min_bytes
        character(len=*), intent(in) :: what
        character(len=24) :: a, b, c
        ok = n >= 0 .and. n <= max(r%fsize, 0_i8)/min_bytes
        if (ok) return
        write (a, '(i0)') n
        write (b, '(i0)') r%fsize
        write (c, '(i0)') max(r%fsize, 0_i8)/min_bytes
        if (n < 0) then
            call fail(r, r%line_no, what//' '//trim(a)//': a count must be >= 0')
        else
            call fail(r, r%line_no, what//' '//trim(a)//', more than a file of '//trim(b)//' bytes can hold (at most '// &
                      trim(c)//')')
        end if
    end function count_fits

    !> A node's coordinates: finite and within max_coordinate.
    logical function coordinates_ok(r, x) result(ok)
        type(gmsh_reader_t), intent(inout) :: r
        real(dp), intent(in) :: x(3)
        character(len=32) :: a
        integer :: j
        ok = .true.
        do j = 1, 3
            if (.not. (abs(x(j)) <= huge(1.0_dp))) then
                call fail(r, r%line_no, 'node coordinate is not finite'); ok = .false.; return
            end if
            if (abs(x(j)) > max_coordinate) then
                write (a, '(es12.3e3)') x(j)
                call fail(r, r%line_no, 'node coordinate '//trim(adjustl(a))//' is out of range (beyond 1e9 in magnitude)')
                ok = .false.; return
            end if
        end do
    end function coordinates_ok

    !> A tetrahedron's four nodes must differ (a repeated node is a degenerate element).
    logical function distinct_nodes(r, t, elem_tag) result(ok)
        type(gmsh_reader_t), intent(inout) :: r
        integer(i8), intent(in) :: t(4), elem_tag
        integer :: a, b
        ok = .true.
        do a = 1, 3
            do b = a + 1, 4
                if (t(a) == t(b)) then
                    call fail(r, r%line_no, 'tetrahedron '//i8_text(elem_tag)//' is degenerate: node '//i8_text(t(a))// &
                              ' is repeated (a tetrahedron has four distinct nodes)')
                    ok = .false.; return
                end if
            end do
        end do
    end function distinct_nodes

    !> 4.1 $Entities: the physical tags of each volume entity (points, curves, surfaces skipped).
    subroutine entities41(r)
        type(gmsh_reader_t), intent(inout) :: r
        character(len=4096) :: line
        integer(i8) :: ncount(4), tag, nphys, phys(1)
        real(dp) :: bb(6)
        integer :: k, j, ios2
        read (r%u, *, iostat=r%ios) ncount
        r%line_no = r%line_no + 1
        if (r%ios /= 0) then
            call fail(r, r%line_no, 'bad $Entities header (expected: points curves surfaces volumes)'); return
        end if
        do j = 1, 4
            if (.not. count_fits(r, ncount(j), 8, '$Entities declares')) return
        end do
        do k = 1, int(ncount(1) + ncount(2) + ncount(3))
            call next_line(r, line)
            if (r%ios /= 0) then
                call fail(r, r%line_no, 'the $Entities section ends early'); return
            end if
        end do
        allocate (r%vol_tag(ncount(4)), r%vol_phys(ncount(4)), r%vol_nphys(ncount(4)))
        do k = 1, int(ncount(4))
            call next_line(r, line)
            phys = 0; ios2 = 0
            if (r%ios == 0) read (line, *, iostat=ios2) tag, bb, nphys
            if (r%ios /= 0 .or. ios2 /= 0) then
                call fail(r, r%line_no, 'bad volume entity line (expected: tag 6 bounds, physical tag count, tags...)')
                return
            end if
            if (nphys >= 1) read (line, *, iostat=ios2) tag, bb, nphys, phys(1)
            if (nphys < 0 .or. ios2 /= 0) then
                call fail(r, r%line_no, 'bad physical tags of volume entity '//i8_text(tag)); return
            end if
            r%vol_tag(k) = tag; r%vol_phys(k) = phys(1); r%vol_nphys(k) = int(min(nphys, 2_i8))
        end do
    end subroutine entities41

    !> Each tetrahedron's body: mesh%body holds the 4.1 entity tag or the 2.2 physical tag when
    !> read; here it becomes the physical volume tag (1 for a mesh without physical volumes).
    subroutine assign_bodies(r)
        type(gmsh_reader_t), intent(inout) :: r
        if (r%version > 3 .and. .not. allocated(r%vol_tag)) return      ! no $Entities: the entity tag
        call by_version(r, bodies_from_entities, bodies_from_physical_tags)
    end subroutine assign_bodies

    !> 4.1: each tetrahedron's volume entity maps to its one physical volume (1 if there are none).
    subroutine bodies_from_entities(r)
        type(gmsh_reader_t), intent(inout) :: r
        integer :: e, k
        logical :: any_phys
        any_phys = any(r%vol_nphys > 0)
        do e = 1, r%mesh%ntet
            k = findloc(r%vol_tag, int(r%mesh%body(e), i8), dim=1)
            r%line_no = r%tet_line(e)
            if (k == 0) then
                call fail(r, r%line_no, 'the tetrahedron''s volume entity '//int_text(r%mesh%body(e))// &
                          ' is not in the $Entities section'); return
            else if (r%vol_nphys(k) > 1) then
                call fail(r, r%line_no, 'volume entity '//int_text(r%mesh%body(e))//' belongs to several physical '// &
                          'volumes (a body is one physical volume: give each volume one)'); return
            else if (r%vol_nphys(k) == 0 .and. any_phys) then
                call fail(r, r%line_no, 'volume entity '//int_text(r%mesh%body(e))//' is in no physical volume '// &
                          'while others are (add it to one: each physical volume is a body)'); return
            end if
            r%mesh%body(e) = 1
            if (any_phys) r%mesh%body(e) = int(r%vol_phys(k))
        end do
    end subroutine bodies_from_entities

    !> 2.2: the physical tag read is the body; all tags 0 is one body, 1.
    subroutine bodies_from_physical_tags(r)
        type(gmsh_reader_t), intent(inout) :: r
        integer :: e
        logical :: any_phys
        any_phys = any(r%mesh%body(1:r%mesh%ntet) /= 0)
        do e = 1, r%mesh%ntet
            if (r%mesh%body(e) == 0 .and. any_phys) then
                r%line_no = r%tet_line(e)
                call fail(r, r%line_no, 'a tetrahedron in no physical volume (tag 0) while others are in one '// &
                          '(each physical volume is a body)'); return
            end if
            if (.not. any_phys) r%mesh%body(e) = 1
        end do
    end subroutine bodies_from_physical_tags

    subroutine nodes41(r)
        type(gmsh_reader_t), intent(inout) :: r
        integer(i8) :: nblocks, nnodes, mintag, maxtag, nb
        integer :: b, k, dim, tag, param, n0
        read (r%u, *, iostat=r%ios) nblocks, nnodes, mintag, maxtag
        r%line_no = r%line_no + 1
        if (r%ios /= 0 .or. nnodes < 1) then
            call fail(r, r%line_no, 'bad $Nodes header (expected: blocks nodes min-tag max-tag)'); return
        end if
        if (.not. count_fits(r, nnodes, 8, '$Nodes declares')) return
        if (.not. count_fits(r, nblocks, 8, '$Nodes declares blocks:')) return
        allocate (r%mesh%node_tag(nnodes), r%mesh%x(3, nnodes))
        n0 = 0
        do b = 1, int(nblocks)
            read (r%u, *, iostat=r%ios) dim, tag, param, nb
            r%line_no = r%line_no + 1
            if (r%ios /= 0 .or. nb < 0 .or. n0 + nb > nnodes) then
                call fail(r, r%line_no, 'bad node block header'); return
            end if
            do k = 1, int(nb)
                read (r%u, *, iostat=r%ios) r%mesh%node_tag(n0 + k)
                r%line_no = r%line_no + 1
                if (r%ios /= 0) then
                    call fail(r, r%line_no, 'bad node tag'); return
                end if
            end do
            do k = 1, int(nb)
                if (.not. node_read(r, 3, 'bad node coordinates (expected: x y z)', r%mesh%x(:, n0 + k))) return
            end do
            n0 = n0 + int(nb)
        end do
        r%mesh%nnode = n0
    end subroutine nodes41

    subroutine nodes22(r)
        type(gmsh_reader_t), intent(inout) :: r
        integer(i8) :: nnodes
        integer :: k
        read (r%u, *, iostat=r%ios) nnodes
        r%line_no = r%line_no + 1
        if (r%ios /= 0 .or. nnodes < 1) then
            call fail(r, r%line_no, 'bad $Nodes count'); return
        end if
        if (.not. count_fits(r, nnodes, 8, '$Nodes declares')) return
        allocate (r%mesh%node_tag(nnodes), r%mesh%x(3, nnodes))
        do k = 1, int(nnodes)
            if (.not. node_read(r, 4, 'bad node line (expected: tag x y z)', r%mesh%x(:, k), r%mesh%node_tag(k))) return
        end do
        r%mesh%nnode = int(nnodes)
    end subroutine nodes22

    !> One node line of ntokens numbers: "x y z" (4.1) or "tag x y z" (2.2), read as text first (a
    !> list-directed read would go on to the next line for a missing coordinate and report the wrong
    !> line); a failure (bad_line) unless it holds exactly that and finite coordinates in range.
    logical function node_read(r, ntokens, bad_line, x, tag) result(ok)
        type(gmsh_reader_t), intent(inout) :: r
        integer, intent(in) :: ntokens
        character(len=*), intent(in) :: bad_line
        real(dp), intent(inout) :: x(3)
        integer(i8), intent(inout), optional :: tag
        character(len=4096) :: node_line
        read (r%u, '(a)', iostat=r%ios) node_line
        r%line_no = r%line_no + 1
        if (r%ios == 0) then
            if (present(tag)) then
                read (node_line, *, iostat=r%ios) tag, x
            else
                read (node_line, *, iostat=r%ios) x
            end if
        end if
        ok = r%ios == 0 .and. count_tokens(node_line) == ntokens
        if (.not. ok) then
            call fail(r, r%line_no, bad_line); return
        end if
        ok = coordinates_ok(r, x)
    end function node_read

    !> After the $Elements header line (read with status ios): room for nelem elements, or a
    !> failure naming the line.
    logical function elements_start(r, nelem, what) result(ok)
        type(gmsh_reader_t), intent(inout) :: r
        integer(i8), intent(in) :: nelem
        character(len=*), intent(in) :: what
        r%line_no = r%line_no + 1
        ok = r%ios == 0
        if (.not. ok) then
            call fail(r, r%line_no, what); return
        end if
        ok = count_fits(r, nelem, 4, '$Elements declares')
        if (.not. ok) return
        allocate (r%mesh%tet(4, nelem), r%mesh%body(nelem), r%mesh%volume(nelem), r%tet_line(nelem))
    end function elements_start

    !> An element type the reader knows: 4 (tetrahedra) read; 15, 1, 2 (points, lines, triangles)
    !> skipped; any other a failure.
    logical function element_type_ok(r, etype) result(ok)
        type(gmsh_reader_t), intent(inout) :: r
        integer, intent(in) :: etype
        ok = etype == 4 .or. etype == 15 .or. etype == 1 .or. etype == 2
        if (.not. ok) call fail(r, r%line_no, 'unsupported element type '//int_text(etype)//' (allowed: 4 = 4-node '// &
                                'tetrahedron; points, lines and triangles are skipped)')
    end function element_type_ok

    !> One more tetrahedron (nodes, body tag as read, volume entity tag) at the current line.
    subroutine add_tet(r, nodes, body, volume)
        type(gmsh_reader_t), intent(inout) :: r
        integer(i8), intent(in) :: nodes(4)
        integer, intent(in) :: body, volume
        r%mesh%ntet = r%mesh%ntet + 1
        r%mesh%tet(:, r%mesh%ntet) = nodes
        r%mesh%body(r%mesh%ntet) = body
        r%mesh%volume(r%mesh%ntet) = volume
        r%tet_line(r%mesh%ntet) = r%line_no
    end subroutine add_tet

    !> 4.1: entity blocks; a tetrahedron keeps its volume entity's tag until assign_bodies.
    subroutine elements41(r)
        type(gmsh_reader_t), intent(inout) :: r
        integer(i8) :: nblocks, nelem, mintag, maxtag, nb, nread
        integer :: b, dim, tag, etype
        read (r%u, *, iostat=r%ios) nblocks, nelem, mintag, maxtag
        if (.not. elements_start(r, nelem, 'bad $Elements header')) return
        if (.not. count_fits(r, nblocks, 8, '$Elements declares blocks:')) return
        nread = 0
        do b = 1, int(nblocks)
            read (r%u, *, iostat=r%ios) dim, tag, etype, nb
            r%line_no = r%line_no + 1
            if (r%ios /= 0 .or. nb < 0) then
                call fail(r, r%line_no, 'bad element block header'); return
            end if
            if (nread + nb > nelem) then
                call fail(r, r%line_no, 'more elements than the $Elements header says ('//i8_text(nelem)//')'); return
            end if
            nread = nread + nb
            if (.not. element_type_ok(r, etype)) return
            call element_block41(r, etype, tag, int(nb))
            if (.not. r%mesh%ok) return
        end do
    end subroutine elements41

    !> The nb element lines of one 4.1 block of type etype in volume entity tag.
    subroutine element_block41(r, etype, tag, nb)
        type(gmsh_reader_t), intent(inout) :: r
        integer, intent(in) :: etype, tag, nb
        character(len=4096) :: line
        integer(i8) :: tags(5)
        integer :: k
        do k = 1, nb
            if (etype == 4) then
                read (r%u, *, iostat=r%ios) tags(1:5)
                r%line_no = r%line_no + 1
                if (r%ios /= 0) then
                    call fail(r, r%line_no, 'bad tetrahedron line (expected: tag n1 n2 n3 n4)'); return
                end if
                if (r%mesh%ntet == size(r%mesh%tet, 2)) then
                    call fail(r, r%line_no, 'more elements than the $Elements header says'); return
                end if
                if (.not. distinct_nodes(r, tags(2:5), tags(1))) return
                call add_tet(r, tags(2:5), tag, tag)
            else
                call next_line(r, line)
                if (r%ios /= 0) then
                    call fail(r, r%line_no, 'the $Elements section ends early'); return
                end if
            end if
        end do
    end subroutine element_block41

    subroutine elements22(r)
        type(gmsh_reader_t), intent(inout) :: r
        character(len=4096) :: line
        integer(i8) :: nelem
        integer :: k, etype, ntags, n, ios2, body, volume
        integer(i8) :: vals(64)
        read (r%u, *, iostat=r%ios) nelem
        if (.not. elements_start(r, nelem, 'bad $Elements count')) return
        do k = 1, int(nelem)
            read (r%u, '(a)', iostat=r%ios) line
            r%line_no = r%line_no + 1
            vals = 0
            read (line, *, iostat=ios2) vals(1:3)
            if (r%ios /= 0 .or. ios2 /= 0) then
                call fail(r, r%line_no, 'bad element line'); return
            end if
            etype = int(vals(2)); ntags = int(vals(3))
            if (.not. element_type_ok(r, etype)) return
            if (etype /= 4) cycle
            n = 3 + ntags + 4
            if (ntags < 0 .or. n > 64) then
                call fail(r, r%line_no, 'bad element line'); return
            end if
            read (line, *, iostat=ios2) vals(1:n)
            if (ios2 /= 0) then
                call fail(r, r%line_no, 'bad tetrahedron line (expected: tag 4 ntags tags... n1 n2 n3 n4)'); return
            end if
            if (.not. distinct_nodes(r, vals(n - 3:n), vals(1))) return
            body = 0                                      ! no physical tag
            if (ntags >= 1) body = int(vals(4))
            volume = 0                                    ! no elementary tag
            if (ntags >= 2) volume = int(vals(5))
            call add_tet(r, vals(n - 3:n), body, volume)
        end do
    end subroutine elements22

    !> Node tags 1..nnode, each once; every tetrahedron's nodes exist.
    subroutine check_nodes(r)
        type(gmsh_reader_t), intent(inout) :: r
        logical, allocatable :: seen(:)
        integer :: k
        allocate (seen(r%mesh%nnode))
        seen = .false.
        do k = 1, r%mesh%nnode
            if (r%mesh%node_tag(k) < 1 .or. r%mesh%node_tag(k) > r%mesh%nnode) then
                call fail(r, 0, 'node tags must be 1..'//int_text(r%mesh%nnode)//' (renumber the mesh: gmsh -renumber)')
                return
            end if
            if (seen(r%mesh%node_tag(k))) then
                call fail(r, 0, 'node tag '//int_text(int(r%mesh%node_tag(k)))//' appears twice'); return
            end if
            seen(r%mesh%node_tag(k)) = .true.
        end do
        do k = 1, r%mesh%ntet
            if (any(r%mesh%tet(:, k) < 1) .or. any(r%mesh%tet(:, k) > r%mesh%nnode)) then
                call fail(r, 0, 'tetrahedron '//int_text(k)//' names a node that is not in the mesh'); return
            end if
        end do
    end subroutine check_nodes

    pure function i8_text(i) result(s)
        integer(i8), intent(in) :: i
        character(len=:), allocatable :: s
        character(len=24) :: b
        write (b, '(i0)') i
        s = trim(b)
    end function i8_text

end module terrace_gmsh_mesh
