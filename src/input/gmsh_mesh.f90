!> Gmsh MSH meshes (ASCII 4.1 and 2.2, as gmsh and meshio write them): nodes (tags are the atom
!> ids) and 4-node tetrahedra (element type 4) with the body each belongs to: its physical volume
!> tag. In MSH 4.1 a tetrahedron's volume entity is mapped to its physical tag through the
!> $Entities section (several entities in one physical volume are one body; a file without
!> $Entities takes the entity tag); in MSH 2.2 the first element tag is the physical tag. A mesh
!> without physical volumes (tag 0, or no physical tag on any volume entity) is one body, 1.
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
        logical :: ok = .true.
        character(len=1024) :: error = ''
    end type mesh_t

    public :: read_gmsh

    real(dp), parameter :: max_coordinate = 1.0e9_dp

contains

    subroutine read_gmsh(path, mesh)
        character(len=*), intent(in) :: path
        type(mesh_t), intent(out) :: mesh
        integer :: u, ios, line_no
        character(len=4096) :: line, node_line
        real(dp) :: version
        integer :: ftype, dsize
        integer(i8) :: fsize
        integer :: nodes_line, elements_line, entities_line
        integer, allocatable :: tet_line(:)          !< (ntet) line of each tetrahedron
        integer(i8), allocatable :: vol_tag(:)       !< MSH 4.1 volume entities: tag,
        integer(i8), allocatable :: vol_phys(:)      !< first physical tag (0: none),
        integer, allocatable :: vol_nphys(:)         !< number of physical tags
        nodes_line = 0; elements_line = 0; entities_line = 0
        inquire (file=path, size=fsize)
        open (newunit=u, file=path, status='old', action='read', iostat=ios)
        if (ios /= 0) then
            call fail(0, 'cannot open the mesh file')
            return
        end if
        line_no = 0
        call next(line)
        if (ios /= 0 .or. trim(line) /= '$MeshFormat') then
            call fail(line_no, 'not a Gmsh MSH file (expected $MeshFormat on the first line)')
            close (u); return
        end if
        call next(line)
        read (line, *, iostat=ios) version, ftype, dsize
        if (ios /= 0) then
            call fail(line_no, 'bad $MeshFormat line (expected: version file-type data-size)')
        else if (ftype /= 0) then
            call fail(line_no, 'binary MSH files are not read: write ASCII (gmsh -format msh41 or -format msh22, or '// &
                      'meshio with binary=False)')
        else if (abs(version - 4.1_dp) > 1.0e-6_dp .and. abs(version - 2.2_dp) > 1.0e-6_dp) then
            call fail(line_no, 'unsupported MSH version (allowed: 4.1, 2.2)')
        end if
        if (.not. mesh%ok) then
            close (u); return
        end if
        do
            call next(line)
            if (ios /= 0) exit
            select case (trim(line))
            case ('$Entities')
                if (entities_line > 0) then
                    call fail(line_no, 'a second $Entities section (the first is at line '//int_text(entities_line)// &
                              '; a mesh file has one)')
                else if (version > 3) then
                    entities_line = line_no
                    call entities41()
                end if
            case ('$Nodes')
                if (nodes_line > 0) then
                    call fail(line_no, 'a second $Nodes section (the first is at line '//int_text(nodes_line)// &
                              '; a mesh file has one)')
                else
                    nodes_line = line_no
                    if (version > 3) then
                        call nodes41()
                    else
                        call nodes22()
                    end if
                end if
            case ('$Elements')
                if (elements_line > 0) then
                    call fail(line_no, 'a second $Elements section (the first is at line '//int_text(elements_line)// &
                              '; a mesh file has one)')
                else
                    elements_line = line_no
                    if (version > 3) then
                        call elements41()
                    else
                        call elements22()
                    end if
                end if
            end select
            if (.not. mesh%ok) exit
        end do
        close (u)
        if (mesh%ok .and. mesh%nnode == 0) call fail(line_no, 'no $Nodes section')
        if (mesh%ok .and. mesh%ntet == 0) call fail(line_no, 'no tetrahedra (element type 4) in the mesh')
        if (mesh%ok) then
            ! room was made for every element the header declared; keep the tetrahedra only
            mesh%tet = mesh%tet(:, 1:mesh%ntet)
            mesh%body = mesh%body(1:mesh%ntet)
            call assign_bodies()
        end if
        if (mesh%ok) call check_nodes()
    contains
        subroutine next(text)
            character(len=*), intent(out) :: text
            read (u, '(a)', iostat=ios) text
            if (ios == 0) line_no = line_no + 1
        end subroutine next

        subroutine fail(at, what)
            integer, intent(in) :: at
            character(len=*), intent(in) :: what
            character(len=16) :: s
            mesh%ok = .false.
            write (s, '(i0)') at
            if (at > 0) then
                mesh%error = path//':'//trim(s)//': &system: mesh_file: '//what
            else
                mesh%error = path//': &system: mesh_file: '//what
            end if
        end subroutine fail

        !> A count the file declares (what: '$Nodes declares %n nodes') is at most what a file of
        !> fsize bytes can hold at min_bytes bytes per item; else a failure naming the line.
        logical function count_fits(n, min_bytes, what) result(ok)
            integer(i8), intent(in) :: n
            integer, intent(in) :: min_bytes
            character(len=*), intent(in) :: what
            character(len=24) :: a, b, c
            ok = n >= 0 .and. n <= max(fsize, 0_i8)/min_bytes
            if (ok) return
            write (a, '(i0)') n
            write (b, '(i0)') fsize
            write (c, '(i0)') max(fsize, 0_i8)/min_bytes
            if (n < 0) then
                call fail(line_no, what//' '//trim(a)//': a count must be >= 0')
            else
                call fail(line_no, what//' '//trim(a)//', more than a file of '//trim(b)//' bytes can hold (at most '// &
                          trim(c)//')')
            end if
        end function count_fits

        !> A node's coordinates: finite and within max_coordinate.
        logical function coordinates_ok(x) result(ok)
            real(dp), intent(in) :: x(3)
            character(len=32) :: a
            integer :: j
            ok = .true.
            do j = 1, 3
                if (.not. (abs(x(j)) <= huge(1.0_dp))) then
                    call fail(line_no, 'node coordinate is not finite'); ok = .false.; return
                end if
                if (abs(x(j)) > max_coordinate) then
                    write (a, '(es12.3e3)') x(j)
                    call fail(line_no, 'node coordinate '//trim(adjustl(a))//' is out of range (beyond 1e9 in magnitude)')
                    ok = .false.; return
                end if
            end do
        end function coordinates_ok

        !> A tetrahedron's four nodes must differ (a repeated node is a degenerate element).
        logical function distinct_nodes(t, elem_tag) result(ok)
            integer(i8), intent(in) :: t(4), elem_tag
            integer :: a, b
            ok = .true.
            do a = 1, 3
                do b = a + 1, 4
                    if (t(a) == t(b)) then
                        call fail(line_no, 'tetrahedron '//i8_text(elem_tag)//' is degenerate: node '//i8_text(t(a))// &
                                  ' is repeated (a tetrahedron has four distinct nodes)')
                        ok = .false.; return
                    end if
                end do
            end do
        end function distinct_nodes

        !> 4.1 $Entities: the physical tags of each volume entity (points, curves, surfaces skipped).
        subroutine entities41()
            integer(i8) :: ncount(4), tag, nphys, phys(1)
            real(dp) :: bb(6)
            integer :: k, j, ios2
            read (u, *, iostat=ios) ncount
            line_no = line_no + 1
            if (ios /= 0) then
                call fail(line_no, 'bad $Entities header (expected: points curves surfaces volumes)'); return
            end if
            do j = 1, 4
                if (.not. count_fits(ncount(j), 8, '$Entities declares')) return
            end do
            do k = 1, int(ncount(1) + ncount(2) + ncount(3))
                call next(line)
                if (ios /= 0) then
                    call fail(line_no, 'the $Entities section ends early'); return
                end if
            end do
            allocate (vol_tag(ncount(4)), vol_phys(ncount(4)), vol_nphys(ncount(4)))
            do k = 1, int(ncount(4))
                call next(line)
                phys = 0; ios2 = 0
                if (ios == 0) read (line, *, iostat=ios2) tag, bb, nphys
                if (ios /= 0 .or. ios2 /= 0) then
                    call fail(line_no, 'bad volume entity line (expected: tag 6 bounds, physical tag count, tags...)')
                    return
                end if
                if (nphys >= 1) read (line, *, iostat=ios2) tag, bb, nphys, phys(1)
                if (nphys < 0 .or. ios2 /= 0) then
                    call fail(line_no, 'bad physical tags of volume entity '//i8_text(tag)); return
                end if
                vol_tag(k) = tag; vol_phys(k) = phys(1); vol_nphys(k) = int(min(nphys, 2_i8))
            end do
        end subroutine entities41

        !> Each tetrahedron's body: mesh%body holds the 4.1 entity tag or the 2.2 physical tag when
        !> read; here it becomes the physical volume tag (1 for a mesh without physical volumes).
        subroutine assign_bodies()
            integer :: e, k
            logical :: any_phys
            if (version > 3 .and. .not. allocated(vol_tag)) return      ! no $Entities: the entity tag
            if (version > 3) then
                any_phys = any(vol_nphys > 0)
                do e = 1, mesh%ntet
                    k = findloc(vol_tag, int(mesh%body(e), i8), dim=1)
                    line_no = tet_line(e)
                    if (k == 0) then
                        call fail(line_no, 'the tetrahedron''s volume entity '//int_text(mesh%body(e))// &
                                  ' is not in the $Entities section'); return
                    else if (vol_nphys(k) > 1) then
                        call fail(line_no, 'volume entity '//int_text(mesh%body(e))//' belongs to several physical '// &
                                  'volumes (a body is one physical volume: give each volume one)'); return
                    else if (vol_nphys(k) == 0 .and. any_phys) then
                        call fail(line_no, 'volume entity '//int_text(mesh%body(e))//' is in no physical volume '// &
                                  'while others are (add it to one: each physical volume is a body)'); return
                    end if
                    mesh%body(e) = 1
                    if (any_phys) mesh%body(e) = int(vol_phys(k))
                end do
            else
                any_phys = any(mesh%body(1:mesh%ntet) /= 0)
                do e = 1, mesh%ntet
                    if (mesh%body(e) == 0 .and. any_phys) then
                        line_no = tet_line(e)
                        call fail(line_no, 'a tetrahedron in no physical volume (tag 0) while others are in one '// &
                                  '(each physical volume is a body)'); return
                    end if
                    if (.not. any_phys) mesh%body(e) = 1
                end do
            end if
        end subroutine assign_bodies

        subroutine nodes41()
            integer(i8) :: nblocks, nnodes, mintag, maxtag, nb
            integer :: b, k, dim, tag, param, n0
            read (u, *, iostat=ios) nblocks, nnodes, mintag, maxtag
            line_no = line_no + 1
            if (ios /= 0 .or. nnodes < 1) then
                call fail(line_no, 'bad $Nodes header (expected: blocks nodes min-tag max-tag)'); return
            end if
            if (.not. count_fits(nnodes, 8, '$Nodes declares')) return
            if (.not. count_fits(nblocks, 8, '$Nodes declares blocks:')) return
            allocate (mesh%node_tag(nnodes), mesh%x(3, nnodes))
            n0 = 0
            do b = 1, int(nblocks)
                read (u, *, iostat=ios) dim, tag, param, nb
                line_no = line_no + 1
                if (ios /= 0 .or. nb < 0 .or. n0 + nb > nnodes) then
                    call fail(line_no, 'bad node block header'); return
                end if
                do k = 1, int(nb)
                    read (u, *, iostat=ios) mesh%node_tag(n0 + k)
                    line_no = line_no + 1
                    if (ios /= 0) then
                        call fail(line_no, 'bad node tag'); return
                    end if
                end do
                do k = 1, int(nb)
                    ! (one line read as text first: a list-directed read would go on to the next line
                    ! for a missing coordinate and report the wrong line)
                    read (u, '(a)', iostat=ios) node_line
                    line_no = line_no + 1
                    if (ios == 0) read (node_line, *, iostat=ios) mesh%x(:, n0 + k)
                    if (ios /= 0 .or. count_tokens(node_line) /= 3) then
                        call fail(line_no, 'bad node coordinates (expected: x y z)'); return
                    end if
                    if (.not. coordinates_ok(mesh%x(:, n0 + k))) return
                end do
                n0 = n0 + int(nb)
            end do
            mesh%nnode = n0
        end subroutine nodes41

        subroutine nodes22()
            integer(i8) :: nnodes
            integer :: k
            read (u, *, iostat=ios) nnodes
            line_no = line_no + 1
            if (ios /= 0 .or. nnodes < 1) then
                call fail(line_no, 'bad $Nodes count'); return
            end if
            if (.not. count_fits(nnodes, 8, '$Nodes declares')) return
            allocate (mesh%node_tag(nnodes), mesh%x(3, nnodes))
            do k = 1, int(nnodes)
                read (u, '(a)', iostat=ios) node_line
                line_no = line_no + 1
                if (ios == 0) read (node_line, *, iostat=ios) mesh%node_tag(k), mesh%x(:, k)
                if (ios /= 0 .or. count_tokens(node_line) /= 4) then
                    call fail(line_no, 'bad node line (expected: tag x y z)'); return
                end if
                if (.not. coordinates_ok(mesh%x(:, k))) return
            end do
            mesh%nnode = int(nnodes)
        end subroutine nodes22

        !> After the $Elements header line (read with status ios): room for nelem elements, or a
        !> failure naming the line.
        logical function elements_start(nelem, what) result(ok)
            integer(i8), intent(in) :: nelem
            character(len=*), intent(in) :: what
            line_no = line_no + 1
            ok = ios == 0
            if (.not. ok) then
                call fail(line_no, what); return
            end if
            ok = count_fits(nelem, 4, '$Elements declares')
            if (.not. ok) return
            allocate (mesh%tet(4, nelem), mesh%body(nelem), tet_line(nelem))
        end function elements_start

        !> 4.1: entity blocks; a tetrahedron keeps its volume entity's tag until assign_bodies.
        subroutine elements41()
            integer(i8) :: nblocks, nelem, mintag, maxtag, nb, tags(5), nread
            integer :: b, k, dim, tag, etype
            read (u, *, iostat=ios) nblocks, nelem, mintag, maxtag
            if (.not. elements_start(nelem, 'bad $Elements header')) return
            if (.not. count_fits(nblocks, 8, '$Elements declares blocks:')) return
            nread = 0
            do b = 1, int(nblocks)
                read (u, *, iostat=ios) dim, tag, etype, nb
                line_no = line_no + 1
                if (ios /= 0 .or. nb < 0) then
                    call fail(line_no, 'bad element block header'); return
                end if
                if (nread + nb > nelem) then
                    call fail(line_no, 'more elements than the $Elements header says ('//i8_text(nelem)//')'); return
                end if
                nread = nread + nb
                if (etype /= 4 .and. etype /= 15 .and. etype /= 1 .and. etype /= 2) then
                    call fail(line_no, 'unsupported element type '//int_text(etype)//' (allowed: 4 = 4-node '// &
                              'tetrahedron; points, lines and triangles are skipped)'); return
                end if
                do k = 1, int(nb)
                    if (etype == 4) then
                        read (u, *, iostat=ios) tags(1:5)
                        line_no = line_no + 1
                        if (ios /= 0) then
                            call fail(line_no, 'bad tetrahedron line (expected: tag n1 n2 n3 n4)'); return
                        end if
                        if (mesh%ntet == size(mesh%tet, 2)) then
                            call fail(line_no, 'more elements than the $Elements header says'); return
                        end if
                        if (.not. distinct_nodes(tags(2:5), tags(1))) return
                        mesh%ntet = mesh%ntet + 1
                        mesh%tet(:, mesh%ntet) = tags(2:5)
                        mesh%body(mesh%ntet) = tag
                        tet_line(mesh%ntet) = line_no
                    else
                        call next(line)
                        if (ios /= 0) then
                            call fail(line_no, 'the $Elements section ends early'); return
                        end if
                    end if
                end do
            end do
        end subroutine elements41

        subroutine elements22()
            integer(i8) :: nelem
            integer :: k, etype, ntags, n, ios2
            integer(i8) :: vals(64)
            read (u, *, iostat=ios) nelem
            if (.not. elements_start(nelem, 'bad $Elements count')) return
            do k = 1, int(nelem)
                read (u, '(a)', iostat=ios) line
                line_no = line_no + 1
                vals = 0
                read (line, *, iostat=ios2) vals(1:3)
                if (ios /= 0 .or. ios2 /= 0) then
                    call fail(line_no, 'bad element line'); return
                end if
                etype = int(vals(2)); ntags = int(vals(3))
                if (etype /= 4 .and. etype /= 15 .and. etype /= 1 .and. etype /= 2) then
                    call fail(line_no, 'unsupported element type '//int_text(etype)//' (allowed: 4 = 4-node '// &
                              'tetrahedron; points, lines and triangles are skipped)'); return
                end if
                if (etype /= 4) cycle
                n = 3 + ntags + 4
                if (ntags < 0 .or. n > 64) then
                    call fail(line_no, 'bad element line'); return
                end if
                read (line, *, iostat=ios2) vals(1:n)
                if (ios2 /= 0) then
                    call fail(line_no, 'bad tetrahedron line (expected: tag 4 ntags tags... n1 n2 n3 n4)'); return
                end if
                if (.not. distinct_nodes(vals(n - 3:n), vals(1))) return
                mesh%ntet = mesh%ntet + 1
                mesh%tet(:, mesh%ntet) = vals(n - 3:n)
                mesh%body(mesh%ntet) = 0                  ! no physical tag
                if (ntags >= 1) mesh%body(mesh%ntet) = int(vals(4))
                tet_line(mesh%ntet) = line_no
            end do
        end subroutine elements22

        !> Node tags 1..nnode, each once; every tetrahedron's nodes exist.
        subroutine check_nodes()
            logical, allocatable :: seen(:)
            integer :: k
            allocate (seen(mesh%nnode))
            seen = .false.
            do k = 1, mesh%nnode
                if (mesh%node_tag(k) < 1 .or. mesh%node_tag(k) > mesh%nnode) then
                    call fail(0, 'node tags must be 1..'//int_text(mesh%nnode)//' (renumber the mesh: gmsh -renumber)')
                    return
                end if
                if (seen(mesh%node_tag(k))) then
                    call fail(0, 'node tag '//int_text(int(mesh%node_tag(k)))//' appears twice'); return
                end if
                seen(mesh%node_tag(k)) = .true.
            end do
            do k = 1, mesh%ntet
                if (any(mesh%tet(:, k) < 1) .or. any(mesh%tet(:, k) > mesh%nnode)) then
                    call fail(0, 'tetrahedron '//int_text(k)//' names a node that is not in the mesh'); return
                end if
            end do
        end subroutine check_nodes
    end subroutine read_gmsh

    pure function i8_text(i) result(s)
        integer(i8), intent(in) :: i
        character(len=:), allocatable :: s
        character(len=24) :: b
        write (b, '(i0)') i
        s = trim(b)
    end function i8_text


end module terrace_gmsh_mesh
