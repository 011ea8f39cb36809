!> The XDMF sidecar of a mesh trajectory: a small XML file beside the H5MD trajectory that tells
!> ParaView (and other XDMF readers) how to see the nodes as a deforming tetrahedral mesh. It holds
!> no data, only references into the trajectory:
!>
!>     <Xdmf Version="3.0"><Domain>
!>       <Grid Name="mesh" GridType="Collection" CollectionType="Temporal">
!>         <Grid Name="frame K" GridType="Uniform">            one per frame, K = 0, 1, ...
!>           <Time Value="t_K"/>
!>           <Topology TopologyType="Tetrahedron" ...>          the connectivity, 0-based rows:
!>             <DataItem ... Format="HDF">traj.h5:/parameters/terrace/tetrahedra_index</DataItem>
!>           <Geometry GeometryType="XYZ">                      frame K of the positions:
!>             <DataItem ItemType="HyperSlab" Dimensions="N 3">
!>               <DataItem Dimensions="3 3" Format="XML">K 0 0  1 1 1  1 N 3</DataItem>
!>               <DataItem Dimensions="F N 3" ... Format="HDF">traj.h5:/particles/all/position/value</DataItem>
!>
!> (start, stride and count of the slab, in C order: frame K, every node, 3 coordinates). The
!> trajectory is named by its file name alone: the sidecar lives in the same directory. The file
!> is written whole under a temporary name and renamed over the old one, so a reader never sees a
!> half-written sidecar; the caller (rank 0) rewrites it as frames reach the disk.
module terrace_xdmf
    use terrace_kinds, only: dp, i8
    use terrace_file_ops, only: rename_file, check_size, output_target, trajectory_sibling
    use terrace_text, only: real_in_format
    implicit none
    private

    public :: xdmf_sidecar_path, write_xdmf_mesh

contains

    !> The sidecar of a trajectory: its path with a final .h5, .h5md or .hdf5 replaced by .xdmf
    !> (cube.h5 -> cube.xdmf), or .xdmf appended to any other name.
    function xdmf_sidecar_path(trajectory) result(path)
        character(len=*), intent(in) :: trajectory
        character(len=:), allocatable :: path
        path = trajectory_sibling(trajectory, '.xdmf')
    end function xdmf_sidecar_path

    !> Write the sidecar `path` for the trajectory `trajectory` (its file name is what the sidecar
    !> refers to) of natoms nodes and ntet tetrahedra, with one grid per frame at times(:).
    !> ok = .false. with msg when the file cannot be written in full. Called by one rank.
    subroutine write_xdmf_mesh(path, trajectory, natoms, ntet, times, ok, msg)
        character(len=*), intent(in) :: path, trajectory
        integer(i8), intent(in) :: natoms, ntet
        real(dp), intent(in) :: times(:)
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        character(len=:), allocatable :: tmp, h5, sn, st, sf, topo, target
        character(len=64) :: buf
        integer :: u, ios, k, p, rc
        integer(i8) :: bytes
        target = output_target(path)       ! a symbolic link stays; its target is replaced
        p = index(target, '/', back=.true.)
        tmp = target(1:p)//'.'//target(p + 1:)//'.terrace-partial'
        p = index(trim(trajectory), '/', back=.true.)
        h5 = xml_escape(trim(trajectory(p + 1:)))
        write (buf, '(i0)') natoms; sn = trim(buf)
        write (buf, '(i0)') ntet; st = trim(buf)
        write (buf, '(i0)') size(times); sf = trim(buf)
        ok = .true.; msg = ''
        bytes = 0
        open (newunit=u, file=tmp, status='replace', action='write', access='stream', form='formatted', iostat=ios, &
              iomsg=msg)
        if (ios /= 0) then
            ok = .false.; msg = 'cannot create '//tmp//': '//trim(msg); return
        end if
        topo = '      <Topology TopologyType="Tetrahedron" NumberOfElements="'//st//'" NodesPerElement="4">'
        call put('<?xml version="1.0" ?>')
        call put('<!-- Written by Terrace: the tetrahedral mesh of the H5MD trajectory '//h5//', one grid per frame '// &
                 '(ParaView: open this file). -->')
        call put('<Xdmf Version="3.0">')
        call put('  <Domain>')
        call put('    <Grid Name="mesh" GridType="Collection" CollectionType="Temporal">')
        do k = 1, size(times)
            write (buf, '(i0)') k - 1
            call put('      <Grid Name="frame '//trim(buf)//'" GridType="Uniform">')
            ! the time in full (17 significant digits: the file's float64 time, read back exactly)
            call put('        <Time Value="'//real_in_format(times(k), '(es24.16e3)')//'"/>')
            call put('  '//topo)
            call put('          <DataItem Dimensions="'//st//' 4" NumberType="Int" Precision="4" Format="HDF">'//h5// &
                     ':/parameters/terrace/tetrahedra_index</DataItem>')
            call put('        </Topology>')
            call put('        <Geometry GeometryType="XYZ">')
            call put('          <DataItem ItemType="HyperSlab" Dimensions="'//sn//' 3" Type="HyperSlab">')
            call put('            <DataItem Dimensions="3 3" Format="XML">'//trim(buf)//' 0 0 1 1 1 1 '//sn//' 3</DataItem>')
            call put('            <DataItem Dimensions="'//sf//' '//sn//' 3" NumberType="Float" Precision="8" '// &
                     'Format="HDF">'//h5//':/particles/all/position/value</DataItem>')
            call put('          </DataItem>')
            call put('        </Geometry>')
            call put('      </Grid>')
        end do
        call put('    </Grid>')
        call put('  </Domain>')
        call put('</Xdmf>')
        if (ios == 0) close (u, iostat=ios, iomsg=msg)
        if (ios /= 0) then
            close (u, status='delete', iostat=k)
            ok = .false.; msg = 'cannot write '//tmp//': '//trim(msg); return
        end if
        call check_size(tmp, bytes, ok, msg)
        if (ok) then
            rc = rename_file(tmp, target)
            ok = rc == 0
            if (.not. ok) then
                write (buf, '(i0)') rc
                msg = 'cannot rename '//tmp//' to '//trim(path)//' (errno '//trim(buf)//')'
            end if
        end if
        if (.not. ok) then
            open (newunit=u, file=tmp, status='old', iostat=ios)
            if (ios == 0) close (u, status='delete', iostat=ios)
        end if

    contains

        subroutine put(line)
            character(len=*), intent(in) :: line
            if (ios /= 0) return
            write (u, '(a)', iostat=ios, iomsg=msg) line
            bytes = bytes + len(line) + 1
        end subroutine put

    end subroutine write_xdmf_mesh

    !> A file name as XML text (&, <, >, " escaped).
    function xml_escape(text) result(s)
        character(len=*), intent(in) :: text
        character(len=:), allocatable :: s
        integer :: i
        s = ''
        do i = 1, len(text)
            select case (text(i:i))
            case ('&'); s = s//'&amp;'
            case ('<'); s = s//'&lt;'
            case ('>'); s = s//'&gt;'
            case ('"'); s = s//'&quot;'
            case default; s = s//text(i:i)
            end select
        end do
    end function xml_escape

end module terrace_xdmf
