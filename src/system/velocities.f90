!> Maxwell-Boltzmann initial velocities at temperature T, independent of the rank count:
!> each component is a normal deviate drawn from a hash of (seed, atom id, component), so atom
!> 17 gets the same velocity on 1 or 64 ranks. Then the total momentum is removed (and, for a
!> scene with no periodic dimension, the angular momentum about the centre of mass), and the
!> velocities are scaled to T exactly, T = 2 KE / (dof k_B), dof = d N - d (as LAMMPS).
module terrace_velocities
    use terrace_kinds, only: dp, i8
    use terrace_vec3, only: cross
    use terrace_atoms, only: atoms_t
    use terrace_units, only: units_t
    use terrace_mpi_env, only: sum_all
    implicit none
    private

    public :: create_velocities, remove_drift, momentum_and_mass, atom_mass, zero_angular_momentum, kinetic_energy, &
              local_mv2, hash_uniform

contains

    !> Uniform deviate in (0, 1) from (seed, id, k); Park-Miller steps mixed with xor-shifts
    !> (all products stay below 2^63).
    pure real(dp) function hash_uniform(seed, id, k) result(u)
        integer(i8), intent(in) :: seed, id
        integer, intent(in) :: k
        integer(i8), parameter :: m = 2147483647_i8, a = 48271_i8
        integer(i8) :: s, t
        integer :: r
        s = 1 + mod(abs(seed), m - 1)
        t = 1 + mod(abs(seed)/(m - 1) + 7919_i8*k, m - 1)
        s = mod(a*s, m)
        s = mod(s + mod(id, m), m - 1) + 1
        s = mod(a*s, m)
        s = mod(s + id/m + t, m - 1) + 1
        do r = 1, 6
            s = mod(a*s, m)
            s = ieor(s, ishft(s, -11))
            s = mod(s, m - 1) + 1
        end do
        t = mod(a*s, m)
        u = (real(s, dp) + real(t, dp)/real(m, dp))/real(m, dp)
        u = min(max(u, 1.0e-300_dp), 1.0_dp - epsilon(1.0_dp))
    end function hash_uniform

    subroutine create_velocities(atoms, units, temperature, seed, dimension, free_scene, natoms)
        type(atoms_t), intent(inout) :: atoms
        type(units_t), intent(in) :: units
        real(dp), intent(in) :: temperature
        integer(i8), intent(in) :: seed, natoms
        integer, intent(in) :: dimension
        logical, intent(in) :: free_scene
        integer :: i, d
        real(dp) :: u1, u2, m, ke, t_now, dof
        real(dp), parameter :: two_pi = 8*atan(1.0_dp)
        do i = 1, atoms%nlocal
            m = atoms%mass(atoms%type(i))
            do d = 1, 3
                u1 = hash_uniform(seed, atoms%id(i), 2*d - 1)
                u2 = hash_uniform(seed, atoms%id(i), 2*d)
                atoms%v(d, i) = sqrt(-2*log(u1))*cos(two_pi*u2)*sqrt(units%boltz*temperature/(m*units%mvv2e))
            end do
            if (dimension == 2) atoms%v(3, i) = 0
        end do
        call remove_drift(atoms)
        if (free_scene) call zero_angular_momentum(atoms, dimension)
        dof = dimension*real(natoms, dp) - dimension
        ke = kinetic_energy(atoms, units)
        if (dof > 0 .and. ke > 0) then
            t_now = 2*ke/(dof*units%boltz)
            atoms%v(:, 1:atoms%nlocal) = atoms%v(:, 1:atoms%nlocal)*sqrt(temperature/t_now)
        end if
    end subroutine create_velocities

    !> KE = mvv2e/2 sum m v^2 over all ranks.
    real(dp) function kinetic_energy(atoms, units) result(ke)
        type(atoms_t), intent(in) :: atoms
        type(units_t), intent(in) :: units
        ke = local_mv2(atoms)
        call sum_all(ke)
        ke = 0.5_dp*units%mvv2e*ke
    end function kinetic_energy

    !> sum m v^2 over this rank's atoms, in index order (no reduction).
    real(dp) function local_mv2(atoms) result(s)
        type(atoms_t), intent(in) :: atoms
        integer :: i
        s = 0
        if (atoms%per_atom_mass) then
            do i = 1, atoms%nlocal
                s = s + atoms%rmass(i)*(atoms%v(1, i)**2 + atoms%v(2, i)**2 + atoms%v(3, i)**2)
            end do
        else
            do i = 1, atoms%nlocal
                s = s + atoms%mass(atoms%type(i))*(atoms%v(1, i)**2 + atoms%v(2, i)**2 + atoms%v(3, i)**2)
            end do
        end if
    end function local_mv2

    !> (total momentum, total mass) of all atoms on all ranks (collective).
    function momentum_and_mass(atoms) result(p)
        type(atoms_t), intent(in) :: atoms
        real(dp) :: p(4)
        integer :: i
        p = 0
        do i = 1, atoms%nlocal
            p(1:3) = p(1:3) + atom_mass(atoms, i)*atoms%v(:, i)
            p(4) = p(4) + atom_mass(atoms, i)
        end do
        call sum_all(p)
    end function momentum_and_mass

    !> The mass of local atom i (per atom for meshes, else per type). Not for hot loops.
    pure real(dp) function atom_mass(atoms, i)
        type(atoms_t), intent(in) :: atoms
        integer, intent(in) :: i
        if (atoms%per_atom_mass) then
            atom_mass = atoms%rmass(i)
        else
            atom_mass = atoms%mass(atoms%type(i))
        end if
    end function atom_mass

    subroutine remove_drift(atoms)
        type(atoms_t), intent(inout) :: atoms
        real(dp) :: p(4)
        integer :: i
        p = momentum_and_mass(atoms)
        if (p(4) <= 0) return
        do i = 1, atoms%nlocal
            atoms%v(:, i) = atoms%v(:, i) - p(1:3)/p(4)
        end do
    end subroutine remove_drift

    !> Remove the rigid rotation omega = I^-1 L about the centre of mass (atoms given unwrapped).
    subroutine zero_angular_momentum(atoms, dimension)
        type(atoms_t), intent(inout) :: atoms
        integer, intent(in) :: dimension
        real(dp) :: s(4), acc(13), com(3), l(3), inertia(3, 3), omega(3), r(3), m, det
        integer :: i
        s = 0
        do i = 1, atoms%nlocal
            m = atoms%mass(atoms%type(i))
            s(1:3) = s(1:3) + m*atoms%x(:, i); s(4) = s(4) + m
        end do
        call sum_all(s)
        if (s(4) <= 0) return
        com = s(1:3)/s(4)
        acc = 0
        do i = 1, atoms%nlocal
            m = atoms%mass(atoms%type(i))
            r = atoms%x(:, i) - com
            acc(1:3) = acc(1:3) + m*cross(r, atoms%v(:, i))
            acc(4) = acc(4) + m*(r(2)**2 + r(3)**2)     ! Ixx
            acc(5) = acc(5) + m*(r(1)**2 + r(3)**2)     ! Iyy
            acc(6) = acc(6) + m*(r(1)**2 + r(2)**2)     ! Izz
            acc(7) = acc(7) - m*r(1)*r(2)               ! Ixy
            acc(8) = acc(8) - m*r(1)*r(3)               ! Ixz
            acc(9) = acc(9) - m*r(2)*r(3)               ! Iyz
        end do
        call sum_all(acc)
        l = acc(1:3)
        if (dimension == 2) then
            if (acc(6) <= 0) return
            omega = [0.0_dp, 0.0_dp, l(3)/acc(6)]
        else
            inertia = reshape([acc(4), acc(7), acc(8), acc(7), acc(5), acc(9), acc(8), acc(9), acc(6)], [3, 3])
            det = inertia(1, 1)*(inertia(2, 2)*inertia(3, 3) - inertia(2, 3)*inertia(3, 2)) - &
                  inertia(1, 2)*(inertia(2, 1)*inertia(3, 3) - inertia(2, 3)*inertia(3, 1)) + &
                  inertia(1, 3)*(inertia(2, 1)*inertia(3, 2) - inertia(2, 2)*inertia(3, 1))
            if (abs(det) < 1.0e-12_dp*max(1.0_dp, maxval(abs(inertia)))**3) return
            omega = solve3(inertia, l, det)
        end if
        do i = 1, atoms%nlocal
            r = atoms%x(:, i) - com
            atoms%v(:, i) = atoms%v(:, i) - cross(omega, r)
        end do
    end subroutine zero_angular_momentum


    pure function solve3(a, b, det) result(x)
        real(dp), intent(in) :: a(3, 3), b(3), det
        real(dp) :: x(3), m(3, 3)
        integer :: k
        do k = 1, 3
            m = a
            m(:, k) = b
            x(k) = (m(1, 1)*(m(2, 2)*m(3, 3) - m(2, 3)*m(3, 2)) - m(1, 2)*(m(2, 1)*m(3, 3) - m(2, 3)*m(3, 1)) + &
                    m(1, 3)*(m(2, 1)*m(3, 2) - m(2, 2)*m(3, 1)))/det
        end do
    end function solve3

end module terrace_velocities
