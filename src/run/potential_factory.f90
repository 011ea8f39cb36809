!> The potential of a scene, from &potential: the one place that maps a style name to a type.
!> LJ: per-pair epsilon and sigma, geometric mixing (Lorentz-Berthelot's sqrt(eps_i eps_j) and
!> sqrt(sigma_i sigma_j)) where a pair is not given, per-pair cutoffs. EAM: the tables of a funcfl,
!> setfl or Finnis-Sinclair file; types without a mass take the file's.
module terrace_potential_factory
    use terrace_kinds, only: dp
    use terrace_config, only: config_t, max_types, max_volumes, is_unset
    use terrace_potential, only: potential_t
    use terrace_lj, only: lj_t
    use terrace_eam, only: eam_t
    use terrace_neohookean, only: neohookean_t
    use terrace_contact, only: contact_t, model_node_face, model_node_node
    use terrace_potential_sum, only: potential_sum_t
    use terrace_walls, only: walls_t
    use terrace_gmsh_mesh, only: mesh_t
    use terrace_stepped_potential, only: stepped_potential_t
    use terrace_errors, only: stop_all, check_all
    implicit none
    private

    !> What the terms of a mesh's potential are set up from and checked against, besides the mesh.
    type :: mesh_start_t
        real(dp), allocatable :: xref(:, :)       !< reference positions by node id
        real(dp), allocatable :: x(:, :)          !< starting positions by node id (xref when not given)
        real(dp), allocatable :: node_mass(:)     !< lumped node masses by id
        logical :: box_known = .false.            !< box_lo, box_hi given (walls = 'box')
        real(dp) :: box_lo(3) = 0, box_hi(3) = 0
    end type mesh_start_t

    public :: make_potential

contains

    !> pot for the deck's &potential with ntypes atom types; mass(t) <= 0 is filled from the
    !> potential file where it has masses (EAM). Collective (errors stop every rank).
    subroutine make_potential(cfg, ntypes, mass, pot, mesh, xstart, node_mass, box_lo, box_hi)
        type(config_t), intent(in) :: cfg
        integer, intent(in) :: ntypes
        real(dp), intent(inout) :: mass(:)
        class(potential_t), allocatable, intent(out) :: pot
        type(mesh_t), intent(in), optional :: mesh      !< neohookean: the elements and reference nodes
        real(dp), intent(in), optional :: xstart(:, :)  !< mesh: starting positions by node id (overlap check)
        real(dp), intent(in), optional :: node_mass(:)  !< mesh: lumped node masses by id (contact's time scale)
        real(dp), intent(in), optional :: box_lo(3), box_hi(3)   !< mesh: the box (walls = 'box')
        integer :: t
        if (cfg%potential == 'neohookean') then
            block
                type(neohookean_t), allocatable :: nh
                type(mesh_start_t) :: st
                logical :: ok
                character(len=512) :: msg
                allocate (nh, st%xref(3, mesh%nnode))
                do t = 1, mesh%nnode
                    st%xref(:, mesh%node_tag(t)) = mesh%x(:, t)
                end do
                if (present(xstart)) then
                    st%x = xstart
                else
                    st%x = st%xref
                end if
                if (present(node_mass)) st%node_mass = node_mass
                st%box_known = present(box_lo) .and. present(box_hi)
                if (st%box_known) then
                    st%box_lo = box_lo; st%box_hi = box_hi
                end if
                if (any(.not. is_unset(cfg%volume_mu))) then
                    block
                        real(dp), allocatable :: elam(:), emu(:)
                        call volume_materials(cfg, mesh, elam, emu)
                        call nh%setup(cfg%lambda, cfg%mu, mesh%tet(:, 1:mesh%ntet), st%xref, ok, msg, elam, emu)
                    end block
                else
                    call nh%setup(cfg%lambda, cfg%mu, mesh%tet(:, 1:mesh%ntet), st%xref, ok, msg)
                end if
                call check_all(ok, trim(cfg%mesh_file)//': &system: mesh_file: '//trim(msg))
                nh%density = cfg%mass_density
                if (count_bodies(mesh%body(1:mesh%ntet)) < 2) then
                    if (.not. is_unset(cfg%contact_stiffness)) call stop_all(cfg%where('potential', 'contact_stiffness')// &
                        ': contact needs two or more bodies (physical volumes); '//trim(cfg%mesh_file)//' has one')
                    if (.not. is_unset(cfg%contact_distance)) call stop_all(cfg%where('potential', 'contact_distance')// &
                        ': contact needs two or more bodies (physical volumes); '//trim(cfg%mesh_file)//' has one')
                    if (cfg%nml%find('potential', 'contact_model') > 0) call stop_all(cfg%where('potential', &
                        'contact_model')//': contact needs two or more bodies (physical volumes); '// &
                        trim(cfg%mesh_file)//' has one')
                    if (cfg%walls == 'none') then
                        nh%global_sums = .true.     ! alone: it sums its energies over the ranks itself, exactly
                        call move_alloc(nh, pot)
                    else
                        block
                            type(potential_sum_t), allocatable :: total
                            class(potential_t), allocatable :: term
                            allocate (total)
                            call move_alloc(nh, term)
                            call total%add(term)
                            call add_walls(cfg, mesh, st, total)
                            call move_alloc(total, pot)
                        end block
                    end if
                else
                    call add_contact(cfg, mesh, st, nh, pot)
                end if
            end block
        else if (cfg%potential == 'hard_sphere' .or. cfg%potential == 'square_well') then
            call new_stepped(cfg, ntypes, pot)
        else if (cfg%potential(1:3) == 'eam') then
            block
                type(eam_t), allocatable :: eam
                logical :: ok
                character(len=1024) :: msg
                allocate (eam)
                call eam%read(trim(cfg%potential), trim(cfg%potential_file), cfg%elements(1:max(ntypes, 1)), ntypes, ok, msg)
                call check_all(ok, trim(msg)//' (&potential file)')
                do t = 1, ntypes
                    if (.not. (mass(t) > 0)) mass(t) = eam%mass(t)
                end do
                call move_alloc(eam, pot)
            end block
        else
            call new_lj(cfg, ntypes, pot)
        end if
    end subroutine make_potential

    !> Several bodies: the elements plus the contact between the bodies (potential_sum_t). Checks the
    !> contact parameters against the mesh and the start for bodies that already touch.
    subroutine add_contact(cfg, mesh, st, nh, pot)
        type(config_t), intent(in) :: cfg
        type(mesh_t), intent(in) :: mesh
        type(mesh_start_t), intent(in) :: st
        type(neohookean_t), allocatable, intent(inout) :: nh
        class(potential_t), allocatable, intent(out) :: pot
        type(contact_t), allocatable :: ct
        type(potential_sum_t), allocatable :: total
        class(potential_t), allocatable :: term
        real(dp) :: youngs, k, d0
        integer :: model
        logical :: ok
        character(len=512) :: msg
        character(len=40) :: s1, s2
        k = -1; d0 = -1
        if (.not. is_unset(cfg%contact_stiffness)) k = cfg%contact_stiffness
        if (.not. is_unset(cfg%contact_distance)) d0 = cfg%contact_distance
        youngs = cfg%mu*(3*cfg%lambda + 2*cfg%mu)/(cfg%lambda + cfg%mu)
        allocate (ct)
        model = model_node_face
        if (cfg%contact_model == 'node_node') model = model_node_node
        call ct%setup(k, d0, youngs, mesh%tet(:, 1:mesh%ntet), mesh%body(1:mesh%ntet), st%xref, st%node_mass, model)
        if (d0 > 0 .and. model == model_node_node) then
            write (s1, '(es10.3)') 0.6_dp*ct%spacing
            write (s2, '(es10.3)') 0.25_dp*ct%min_body_extent
            if (d0 < 0.6_dp*ct%spacing .or. d0 > 0.25_dp*ct%min_body_extent) call stop_all(cfg%where('potential', &
                'contact_distance')//': allowed '//trim(adjustl(s1))//' .. '//trim(adjustl(s2))//' '// &
                trim(cfg%units%length)//" for this mesh with contact_model = 'node_node' (from 0.6 x the mean "// &
                'boundary edge, below which a node slips between the nodes of the other body, to a quarter of '// &
                'the smallest body)')
        else if (d0 > 0) then
            write (s1, '(es10.3)') 1.0e-3_dp*ct%spacing
            write (s2, '(es10.3)') 0.25_dp*ct%min_body_extent
            if (d0 < 1.0e-3_dp*ct%spacing .or. d0 > 0.25_dp*ct%min_body_extent) call stop_all(cfg%where('potential', &
                'contact_distance')//': allowed '//trim(adjustl(s1))//' .. '//trim(adjustl(s2))//' '// &
                trim(cfg%units%length)//' for this mesh (from 1e-3 x the mean boundary edge: a thinner barrier, and '// &
                'the skin of half of it, would have the contact search rebuilt at every step; to a quarter of the '// &
                'smallest body)')
        end if
        call ct%check_start(st%x, mesh%tet(:, 1:mesh%ntet), mesh%body(1:mesh%ntet), ok, msg)
        call check_all(ok, trim(cfg%mesh_file)//': &system: mesh_file: '//trim(msg))
        allocate (total)
        call move_alloc(nh, term)
        call total%add(term)
        call move_alloc(ct, term)
        call total%add(term)
        if (cfg%walls /= 'none') call add_walls(cfg, mesh, st, total)
        call move_alloc(total, pot)
    end subroutine add_contact

    !> The deck's walls (&potential walls: the box's six faces, or wall_planes) as a term of total;
    !> a start with a boundary node within wall_distance of a wall is refused.
    subroutine add_walls(cfg, mesh, st, total)
        type(config_t), intent(in) :: cfg
        type(mesh_t), intent(in) :: mesh
        type(mesh_start_t), intent(in) :: st
        type(potential_sum_t), intent(inout) :: total
        type(walls_t), allocatable :: wl
        class(potential_t), allocatable :: term
        real(dp), allocatable :: planes(:, :)
        real(dp) :: k, d0, youngs
        integer :: d
        logical :: ok
        character(len=512) :: msg
        if (cfg%walls == 'box') then
            if (.not. st%box_known) call stop_all(cfg%where('potential', 'walls')// &
                " = 'box': the box is not known here")
            allocate (planes(6, 6))
            do d = 1, 3            ! the lower face's normal points up, the upper face's down
                planes(:, 2*d - 1) = 0; planes(d, 2*d - 1) = st%box_lo(d); planes(3 + d, 2*d - 1) = 1
                planes(:, 2*d) = 0; planes(d, 2*d) = st%box_hi(d); planes(3 + d, 2*d) = -1
            end do
        else
            planes = cfg%wall_planes(:, 1:cfg%nwall_planes/6)
        end if
        k = -1; d0 = -1
        if (.not. is_unset(cfg%wall_stiffness)) k = cfg%wall_stiffness
        if (.not. is_unset(cfg%wall_distance)) d0 = cfg%wall_distance
        youngs = cfg%mu*(3*cfg%lambda + 2*cfg%mu)/(cfg%lambda + cfg%mu)
        allocate (wl)
        call wl%setup(planes, k, d0, youngs, mesh%tet(:, 1:mesh%ntet), st%xref, st%node_mass)
        call wl%check_start(st%x, ok, msg)
        call check_all(ok, cfg%where('potential', 'walls')//': '//trim(cfg%mesh_file)//': '//trim(msg))
        call move_alloc(wl, term)
        call total%add(term)
    end subroutine add_walls

    !> Each element's Lame constants: those of its volume entity where &potential volume_lambda(v),
    !> volume_mu(v) give them, else lambda and mu. A volume the mesh does not have is refused with
    !> the volumes it has.
    subroutine volume_materials(cfg, mesh, elam, emu)
        type(config_t), intent(in) :: cfg
        type(mesh_t), intent(in) :: mesh
        real(dp), allocatable, intent(out) :: elam(:), emu(:)
        integer :: e, v
        character(len=16) :: sv
        character(len=:), allocatable :: have
        allocate (elam(mesh%ntet), emu(mesh%ntet))
        elam = cfg%lambda; emu = cfg%mu
        do e = 1, mesh%ntet
            v = mesh%volume(e)
            if (v < 1 .or. v > max_volumes) cycle
            if (is_unset(cfg%volume_mu(v))) cycle
            elam(e) = cfg%volume_lambda(v); emu(e) = cfg%volume_mu(v)
        end do
        do v = 1, max_volumes
            if (is_unset(cfg%volume_mu(v))) cycle
            if (any(mesh%volume(1:mesh%ntet) == v)) cycle
            have = ''
            do e = 1, max_volumes
                if (.not. any(mesh%volume(1:mesh%ntet) == e)) cycle
                write (sv, '(i0)') e
                if (len(have) > 0) have = have//', '
                have = have//trim(sv)
            end do
            if (len(have) == 0) have = 'none: its tetrahedra carry no volume entity tag'
            write (sv, '(a,i0,a)') '(', v, ')'
            call stop_all(cfg%where('potential', 'volume_mu')//trim(sv)//': '//trim(cfg%mesh_file)// &
                          ' has no tetrahedra in volume entity '//trim(sv(2:len_trim(sv) - 1))//' (its volumes: '// &
                          have//')')
        end do
    end subroutine volume_materials

    pure integer function count_bodies(body) result(n)
        integer, intent(in) :: body(:)
        integer :: b
        n = 0
        do b = minval(body), maxval(body)
            if (any(body == b)) n = n + 1
        end do
    end function count_bodies

    !> An LJ potential with its tables: per-pair epsilon, sigma (geometric mixing where a pair is not
    !> given) and cutoff.
    subroutine new_lj(cfg, ntypes, pot)
        type(config_t), intent(in) :: cfg
        integer, intent(in) :: ntypes
        class(potential_t), allocatable, intent(out) :: pot
        type(lj_t), allocatable :: lj
        real(dp) :: cut(max_types, max_types), eps(max_types, max_types), sig(max_types, max_types)
        integer :: t, i
        character(len=64) :: s1
        allocate (lj)
        do t = 1, ntypes
            if (is_unset(cfg%epsilon(t, t)) .or. is_unset(cfg%sigma(t, t))) then
                write (s1, '(i0)') t
                call stop_all(cfg%path//': &potential: epsilon: type '//trim(s1)//' needs epsilon('//trim(s1)//','// &
                              trim(s1)//') and sigma('//trim(s1)//','//trim(s1)//')')
            end if
        end do
        do t = 1, ntypes
            do i = 1, ntypes
                eps(i, t) = pick(cfg%epsilon, i, t, sqrt(cfg%epsilon(i, i)*cfg%epsilon(t, t)))
                sig(i, t) = pick(cfg%sigma, i, t, sqrt(cfg%sigma(i, i)*cfg%sigma(t, t)))
                cut(i, t) = pick(cfg%pair_cutoff, i, t, cfg%cutoff)
            end do
        end do
        if (cfg%precision == 'mixed' .and. ntypes > 1) then
            write (s1, '(i0)') ntypes
            call stop_all(cfg%where('potential', 'precision')//" = 'mixed': only for one atom type (this scene has "// &
                          trim(s1)//"; allowed with several types: 'double')")
        end if
        call lj%setup(ntypes, eps, sig, cut, cfg%shift, cfg%potential == 'lj/smooth/linear', &
                      mixed=cfg%precision == 'mixed')
        call move_alloc(lj, pot)
    end subroutine new_lj

    !> A hard-sphere or square-well potential with its tables: per-pair diameter (arithmetic mean
    !> of the two types' where a pair is not given, additive spheres), well depth (geometric mean)
    !> and outer radius (well_radius, or well_lambda x diameter, lambda the arithmetic mean).
    subroutine new_stepped(cfg, ntypes, pot)
        type(config_t), intent(in) :: cfg
        integer, intent(in) :: ntypes
        class(potential_t), allocatable, intent(out) :: pot
        type(stepped_potential_t), allocatable :: sp
        integer :: t, i
        real(dp) :: d, eps, rw, lam
        character(len=16) :: s1
        allocate (sp)
        sp%style = trim(cfg%potential)
        do t = 1, ntypes
            write (s1, '(i0)') t
            if (is_unset(cfg%diameter(t, t))) call stop_all(cfg%path//': &potential: diameter: type '//trim(s1)// &
                ' needs diameter('//trim(s1)//','//trim(s1)//')')
            if (cfg%potential == 'square_well' .and. (is_unset(cfg%well_depth(t, t)) .or. &
                (is_unset(cfg%well_lambda(t, t)) .and. is_unset(cfg%well_radius(t, t))))) &
                call stop_all(cfg%path//': &potential: well_depth: type '//trim(s1)//' needs well_depth('//trim(s1)// &
                              ','//trim(s1)//') and well_lambda('//trim(s1)//','//trim(s1)//') or well_radius')
        end do
        call sp%table%init(ntypes)
        do t = 1, ntypes
            do i = t, ntypes
                d = pick(cfg%diameter, i, t, 0.5_dp*(cfg%diameter(i, i) + cfg%diameter(t, t)))
                if (cfg%potential == 'hard_sphere') then
                    call sp%table%set_pair(i, t, [d], [real(dp) ::])
                    cycle
                end if
                eps = pick(cfg%well_depth, i, t, sqrt(cfg%well_depth(i, i)*cfg%well_depth(t, t)))
                if (.not. is_unset(cfg%well_radius(i, t))) then
                    rw = cfg%well_radius(i, t)
                else if (.not. is_unset(cfg%well_radius(t, i))) then
                    rw = cfg%well_radius(t, i)
                else
                    lam = pick(cfg%well_lambda, i, t, 0.5_dp*(lambda_of(i) + lambda_of(t)))
                    rw = lam*d
                end if
                if (.not. (rw > d)) call stop_all(cfg%where('potential', 'well_radius')//': the well of a type '// &
                    'pair must reach beyond its diameter')
                call sp%table%set_pair(i, t, [rw, d], [-eps])
            end do
        end do
        call move_alloc(sp, pot)
    contains
        real(dp) function lambda_of(k)
            integer, intent(in) :: k
            if (.not. is_unset(cfg%well_lambda(k, k))) then
                lambda_of = cfg%well_lambda(k, k)
            else
                lambda_of = cfg%well_radius(k, k)/cfg%diameter(k, k)
            end if
        end function lambda_of
    end subroutine new_stepped

    pure real(dp) function pick(table, i, j, fallback) result(v)
        real(dp), intent(in) :: table(:, :), fallback
        integer, intent(in) :: i, j
        if (.not. is_unset(table(i, j))) then
            v = table(i, j)
        else if (.not. is_unset(table(j, i))) then
            v = table(j, i)
        else
            v = fallback
        end if
    end function pick

end module terrace_potential_factory
