!> Gmsh MSH meshes (ASCII 4.1 and 2.2, the formats gmsh and meshio write): nodes (tags are the
!> atom ids) and 4-node tetrahedra (element type 4) with the physical volume each belongs to (one
!> body per physical volume; tetrahedra without one form body 1). Points, lines and triangles
!> (types 15, 1, 2: physical surfaces and curves) are skipped; any other element type in the file is
!> refused. Errors name the file and line.
module terrace_gmsh_mesh
    use terrace_kinds, only: dp, i8
    use terrace_text, only: int_text
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

contains

    subroutine read_gmsh(path, mesh)
        character(len=*), intent(in) :: path
        type(mesh_t), intent(out) :: mesh
        integer :: u, ios, line_no
        character(len=4096) :: line
        real(dp) :: version
        integer :: ftype, dsize
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
            case ('$Nodes')
                if (version > 3) then
                    call nodes41()
                else
                    call nodes22()
                end if
            case ('$Elements')
                if (version > 3) then
                    call elements41()
                else
                    call elements22()
                end if
            end select
            if (.not. mesh%ok) exit
        end do
        close (u)
        if (mesh%ok .and. mesh%nnode == 0) call fail(line_no, 'no $Nodes section')
        if (mesh%ok .and. mesh%ntet == 0) call fail(line_no, 'no tetrahedra (element type 4) in the mesh')
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

        subroutine nodes41()
            integer(i8) :: nblocks, nnodes, mintag, maxtag, nb
            integer :: b, k, dim, tag, param, n0
            read (u, *, iostat=ios) nblocks, nnodes, mintag, maxtag
            line_no = line_no + 1
            if (ios /= 0 .or. nnodes < 1 .or. nnodes > 100000000_i8) then
                call fail(line_no, 'bad $Nodes header'); return
            end if
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
                    read (u, *, iostat=ios) mesh%x(:, n0 + k)
                    line_no = line_no + 1
                    if (ios /= 0) then
                        call fail(line_no, 'bad node coordinates'); return
                    end if
                    if (any(.not. (abs(mesh%x(:, n0 + k)) <= huge(1.0_dp)))) then
                        call fail(line_no, 'node coordinate is not finite'); return
                    end if
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
            if (ios /= 0 .or. nnodes < 1 .or. nnodes > 100000000_i8) then
                call fail(line_no, 'bad $Nodes count'); return
            end if
            allocate (mesh%node_tag(nnodes), mesh%x(3, nnodes))
            do k = 1, int(nnodes)
                read (u, *, iostat=ios) mesh%node_tag(k), mesh%x(:, k)
                line_no = line_no + 1
                if (ios /= 0) then
                    call fail(line_no, 'bad node line (expected: tag x y z)'); return
                end if
                if (any(.not. (abs(mesh%x(:, k)) <= huge(1.0_dp)))) then
                    call fail(line_no, 'node coordinate is not finite'); return
                end if
            end do
            mesh%nnode = int(nnodes)
        end subroutine nodes22

        !> After the $Elements header line (read with status ios): room for nelem elements, or a
        !> failure naming the line.
        logical function elements_start(nelem, what) result(ok)
            integer(i8), intent(in) :: nelem
            character(len=*), intent(in) :: what
            line_no = line_no + 1
            ok = ios == 0 .and. nelem >= 0 .and. nelem <= 1000000000_i8
            if (.not. ok) then
                call fail(line_no, what); return
            end if
            allocate (mesh%tet(4, nelem), mesh%body(nelem))
        end function elements_start

        !> 4.1: entity blocks; physical tags of volumes come from $Entities, which this reader does not
        !> parse: the volume entity's tag is taken as its body (gmsh writes one volume per body).
        subroutine elements41()
            integer(i8) :: nblocks, nelem, mintag, maxtag, nb, tags(5)
            integer :: b, k, dim, tag, etype
            read (u, *, iostat=ios) nblocks, nelem, mintag, maxtag
            if (.not. elements_start(nelem, 'bad $Elements header')) return
            do b = 1, int(nblocks)
                read (u, *, iostat=ios) dim, tag, etype, nb
                line_no = line_no + 1
                if (ios /= 0 .or. nb < 0) then
                    call fail(line_no, 'bad element block header'); return
                end if
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
                        mesh%ntet = mesh%ntet + 1
                        mesh%tet(:, mesh%ntet) = tags(2:5)
                        mesh%body(mesh%ntet) = tag
                    else
                        read (u, '(a)', iostat=ios) line
                        line_no = line_no + 1
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
                mesh%ntet = mesh%ntet + 1
                mesh%tet(:, mesh%ntet) = vals(n - 3:n)
                mesh%body(mesh%ntet) = 1
                if (ntags >= 1) mesh%body(mesh%ntet) = int(vals(4))
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


end module terrace_gmsh_mesh
