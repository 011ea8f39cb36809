!> Temperature control: the velocity operators that velocity Verlet and energy stepping call to
!> sample the canonical ensemble at the target temperature T(t) = T0 + (T1 - T0) t / t_run.
!>
!>   Langevin (BAOAB, Leimkuhler & Matthews): the O step is the exact Ornstein-Uhlenbeck update
!>     v <- c1 v + sqrt(1 - c1^2) sqrt(k_B T / m) z,   c1 = exp(-dt / damping),
!>     fused with the two half drifts around it (x += dt/2 v; O; x += dt/2 v).
!>   CSVR (Bussi, Donadio & Parrinello 2007): over a time s the total kinetic energy K becomes
!>     K' = K + (1 - c)(K_T (R1^2 + S) / Nf - K) + 2 R1 sqrt(c (1 - c) K K_T / Nf),
!>     c = exp(-s / damping), K_T = Nf k_B T / 2, R1 normal, S chi-square(Nf - 1); v <- v sqrt(K'/K).
!>   Nose-Hoover chains (Martyna, Klein & Tuckerman 1992; the Trotter half step of Martyna,
!>     Tuckerman, Tobias & Klein 1996 with third-order Suzuki-Yoshida weights): chain of M
!>     thermostats, masses Q1 = Nf k_B T damping^2, Qj = k_B T damping^2, forces
!>     G1 = (2K - Nf k_B T)/Q1, Gj = (Q_{j-1} v_{j-1}^2 - k_B T)/Qj; v <- v exp(-dt v_1 ...).
!>   Andersen: each atom's velocity is replaced by a Maxwell-Boltzmann one at rate 1/damping, at
!>     the points of a Poisson process per atom (below); with velocity Verlet in the step whose
!>     span holds a point (probability 1 - exp(-dt/damping)), with energy stepping at the exact
!>     collision times.
!>
!> Every random number is drawn from the counter-based generator keyed by (seed, stream, atom id,
!> step or event), never by rank or by order of atoms: a run gives the same trajectory on any rank
!> count and continues bitwise after a restart. Andersen collision times for energy stepping are a
!> stateless function of (seed, id, time): time is cut into slots of width `damping`; in slot k the
!> atom's collisions are at k damping + damping (E_1 + ... + E_j) for the partial sums below one,
!> E_i exponential draws keyed by (id, k). The slots' points together are a Poisson process of rate
!> 1/damping (independent increments), and the next collision after t is found from (id, t) alone,
!> so nothing per atom needs to go into a checkpoint. Velocity Verlet keeps each atom's next
!> collision time with the atom (atoms%clock) so that a step touches only the colliding atoms;
!> energy stepping recomputes them after every list build.
!>
!> Each operator adds the kinetic energy it changed to ecouple (energy put in by the thermostat),
!> so that etotal - ecouple (econserve) measures the integrator's own error. Per-atom operators
!> keep a per-rank partial sum, folded into the global value (one sum) at samples and checkpoints.
module terrace_thermostat
    use terrace_kinds, only: dp, i8
    use terrace_atoms, only: atoms_t, clock_unset
    use terrace_velocities, only: momentum_and_mass, local_mv2, atom_mass
    use terrace_mpi_env, only: sum_all
    use terrace_counter_rng, only: rng_block, rng_stream, rng_stream_t, unit_from_word, box_muller, &
                                   normals3_many, rng_batch
    use terrace_config, only: config_t
    use terrace_checkpoint, only: ckpt_values_t
    implicit none
    private

    integer, parameter, public :: thermostat_none = 0, thermostat_langevin = 1, thermostat_csvr = 2, &
                                  thermostat_nose_hoover = 3, thermostat_andersen = 4
    character(len=12), parameter, public :: thermostat_names(0:4) = [character(len=12) :: 'none', 'langevin', &
                                                                     'csvr', 'nose_hoover', 'andersen']

    ! streams of the counter-based generator, one per purpose (103, the per-step Andersen choice of
    ! earlier versions, is retired: Verlet's Andersen collisions now come from the collision times)
    integer, parameter :: stream_langevin = 101, stream_csvr = 102, &
                          stream_andersen_velocity = 104, stream_andersen_time = 105, stream_andersen_global = 106

    type, public :: thermostat_t
        integer :: style = thermostat_none
        real(dp) :: t_start = 0, t_end = 0      !< target temperature at time 0 and at run_time
        real(dp) :: run_time = 0                !< length of the ramp
        real(dp) :: damping = 1                 !< relaxation time (Langevin 1/gamma, CSVR tau, NHC tau, Andersen 1/rate)
        integer :: chain_length = 3
        integer(i8) :: seed = 1
        logical :: zero_momentum = .false.
        integer :: dimension = 3
        real(dp) :: dof = 0                     !< degrees of freedom of the thermostatted kinetic energy
        real(dp) :: boltz = 1, mvv2e = 1
        real(dp) :: ecouple_global = 0          !< energy put in, the same on every rank
        real(dp) :: ecouple_local = 0           !< this rank's part not yet folded into ecouple_global
        real(dp), allocatable :: eta(:), v_eta(:)   !< Nose-Hoover chain positions and velocities
        ! energy stepping at scheduled times: CSVR rescaling, or the global Andersen variant (every
        ! atom's velocity resampled), at every multiple of interval (0: none); the next one the
        ! n_rescale-th (its draws keyed by n_rescale)
        real(dp) :: interval = 0
        integer(i8) :: n_rescale = 1
        ! Andersen with energy stepping: next collision time of each owned atom (same order as atoms)
        real(dp), allocatable :: next_collision(:)
        integer(i8), allocatable :: collision_slot(:)
        integer, allocatable :: collision_index(:)
    contains
        procedure :: init => ts_init
        procedure :: configure => ts_configure
        procedure :: save => ts_save
        procedure :: restore => ts_restore
        procedure :: target => ts_target
        procedure :: active => ts_active
        procedure :: langevin_kick_drift => ts_langevin_kick_drift
        procedure :: csvr => ts_csvr
        procedure :: rescale_time => ts_rescale_time
        procedure :: rescale => ts_rescale
        procedure :: nose_hoover => ts_nose_hoover
        procedure :: andersen_step => ts_andersen_step
        procedure :: remove_momentum => ts_remove_momentum
        procedure :: ecouple => ts_ecouple
        procedure :: fold => ts_fold
        procedure :: chain_energy => ts_chain_energy
        procedure :: andersen_schedule => ts_andersen_schedule
        procedure :: andersen_first => ts_andersen_first
        procedure :: andersen_collide => ts_andersen_collide
    end type thermostat_t

    public :: thermostat_style, thermostat_dof, andersen_next_collision

contains

    !> Style code of a name (-1 when unknown).
    pure integer function thermostat_style(name) result(style)
        character(len=*), intent(in) :: name
        integer :: k
        style = -1
        do k = 0, 4
            if (trim(name) == trim(thermostat_names(k))) style = k
        end do
    end function thermostat_style

    !> Degrees of freedom of the thermostatted kinetic energy: d N, less d when the total momentum
    !> is held (zero_momentum, or the deterministic CSVR and Nose-Hoover, which keep a zero total
    !> momentum zero), as for the unthermostatted run (no thermostat: d N - d, as LAMMPS).
    pure real(dp) function thermostat_dof(style, zero_momentum, dimension, natoms) result(dof)
        integer, intent(in) :: style, dimension
        logical, intent(in) :: zero_momentum
        integer(i8), intent(in) :: natoms
        dof = real(dimension, dp)*real(natoms, dp)
        if (zero_momentum .or. style == thermostat_none .or. style == thermostat_csvr .or. &
            style == thermostat_nose_hoover) dof = dof - dimension
        dof = max(dof, 0.0_dp)
    end function thermostat_dof

    subroutine ts_init(self, style, t_start, t_end, run_time, damping, chain_length, seed, zero_momentum, &
                               dimension, natoms, boltz, mvv2e)
        class(thermostat_t), intent(inout) :: self
        integer, intent(in) :: style, chain_length, dimension
        real(dp), intent(in) :: t_start, t_end, run_time, damping, boltz, mvv2e
        integer(i8), intent(in) :: seed, natoms
        logical, intent(in) :: zero_momentum
        self%style = style
        self%t_start = t_start; self%t_end = t_end; self%run_time = run_time
        self%damping = damping; self%chain_length = max(chain_length, 1)
        self%seed = seed; self%zero_momentum = zero_momentum
        self%dimension = dimension
        self%boltz = boltz; self%mvv2e = mvv2e
        self%dof = thermostat_dof(style, zero_momentum, dimension, natoms)
        self%ecouple_global = 0; self%ecouple_local = 0
        if (allocated(self%eta)) deallocate (self%eta, self%v_eta)
        allocate (self%eta(self%chain_length), self%v_eta(self%chain_length))
        self%eta = 0; self%v_eta = 0
    end subroutine ts_init

    !> From the validated &thermostat group; run_time is the length of the temperature ramp.
    subroutine ts_configure(self, cfg, natoms, run_time)
        class(thermostat_t), intent(inout) :: self
        type(config_t), intent(in) :: cfg
        integer(i8), intent(in) :: natoms
        real(dp), intent(in) :: run_time
        call self%init(max(0, thermostat_style(cfg%thermostat)), cfg%thermostat_temperature, &
                       cfg%thermostat_temperature_end, run_time, cfg%thermostat_damping, cfg%chain_length, &
                       cfg%thermostat_seed, cfg%zero_momentum, cfg%dimension, natoms, cfg%units%boltz, cfg%units%mvv2e)
        self%interval = 0
        self%n_rescale = 1
        if (cfg%integrator == 'energy_stepping' .and. cfg%thermostat_interval > 0 .and. &
            (self%style == thermostat_csvr .or. self%style == thermostat_andersen)) self%interval = cfg%thermostat_interval
    end subroutine ts_configure

    !> The thermostat's state for a checkpoint: ecouple (folded: collective) and the chain.
    subroutine ts_save(self, values)
        class(thermostat_t), intent(inout) :: self
        type(ckpt_values_t), intent(inout) :: values
        character(len=16) :: tag
        integer :: j
        real(dp) :: e
        e = self%ecouple()
        call values%put('ts_ecouple', e)
        if (self%interval > 0) call values%put('ts_n_rescale', self%n_rescale)
        do j = 1, self%chain_length
            write (tag, '(i0)') j
            call values%put('ts_eta_'//trim(tag), self%eta(j))
            call values%put('ts_v_eta_'//trim(tag), self%v_eta(j))
        end do
    end subroutine ts_save

    subroutine ts_restore(self, values, ok)
        class(thermostat_t), intent(inout) :: self
        type(ckpt_values_t), intent(in) :: values
        logical, intent(inout) :: ok
        character(len=16) :: tag
        integer :: j
        self%ecouple_global = values%get_r('ts_ecouple', ok)
        self%ecouple_local = 0
        if (self%interval > 0) self%n_rescale = values%get_i('ts_n_rescale', ok)
        do j = 1, self%chain_length
            write (tag, '(i0)') j
            self%eta(j) = values%get_r('ts_eta_'//trim(tag), ok)
            self%v_eta(j) = values%get_r('ts_v_eta_'//trim(tag), ok)
        end do
    end subroutine ts_restore

    pure logical function ts_active(self)
        class(thermostat_t), intent(in) :: self
        ts_active = self%style /= thermostat_none
    end function ts_active

    !> Target temperature at time t (linear ramp from t_start at 0 to t_end at run_time).
    pure real(dp) function ts_target(self, t) result(temp)
        class(thermostat_t), intent(in) :: self
        real(dp), intent(in) :: t
        real(dp) :: f
        f = 0
        if (self%run_time > 0) f = min(max(t/self%run_time, 0.0_dp), 1.0_dp)
        temp = self%t_start + (self%t_end - self%t_start)*f
    end function ts_target

    !> BAOAB's B A O A for every owned atom: v += dtfm f, x += dt/2 v, v <- c1 v + c2 sqrt(kT/m) z,
    !> x += dt/2 v, z from (seed, id, step); dtfm(type) = dt/2 ftm2v/m. `time` is the middle of the
    !> step (for the target temperature).
    subroutine ts_langevin_kick_drift(self, atoms, dtfm, dt, step, time)
        class(thermostat_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        real(dp), intent(in) :: dtfm(:), dt, time
        integer(i8), intent(in) :: step
        real(dp) :: c1, c2, kt, half, sig(atoms%ntypes), z(rng_batch, 3), de, m2(atoms%ntypes)
        integer :: t, i0, i1, nb
        c1 = exp(-dt/self%damping)
        c2 = sqrt(max(0.0_dp, 1 - c1*c1))
        kt = self%boltz*self%target(time)
        do t = 1, atoms%ntypes
            sig(t) = c2*sqrt(kt/(atoms%mass(t)*self%mvv2e))
            m2(t) = 0.5_dp*self%mvv2e*atoms%mass(t)
        end do
        half = 0.5_dp*dt
        de = 0
        ! batches of atoms: the counter-based draws vectorise across atoms (normals3_many), and so
        ! does the B A O A update of the batch (baoab_batch)
        do i0 = 1, atoms%nlocal, rng_batch
            nb = min(rng_batch, atoms%nlocal - i0 + 1)
            i1 = i0 + nb - 1
            call normals3_many(nb, self%seed, stream_langevin, atoms%id(i0:i1), step, z(1:nb, :))
            if (self%dimension == 2) z(1:nb, 3) = 0
            call baoab_batch(nb, atoms%x(:, i0:i1), atoms%v(:, i0:i1), atoms%f(:, i0:i1), atoms%type(i0:i1), &
                             z(1:nb, 1), z(1:nb, 2), z(1:nb, 3), dtfm, sig, m2, c1, half, de)
        end do
        self%ecouple_local = self%ecouple_local + de
    end subroutine ts_langevin_kick_drift

    !> B A O A on a batch of n atoms (explicit-shape arrays: no aliasing, so the loop vectorises):
    !> v' = v + dtfm f, x += dt/2 v', v'' = c1 v' + sig z, x += dt/2 v''; de gains the kinetic
    !> energy the O step put in (per-atom parts summed in atom order).
    pure subroutine baoab_batch(n, x, v, f, typ, z1, z2, z3, dtfm, sig, m2, c1, half, de)
        integer, intent(in) :: n, typ(n)
        real(dp), intent(inout) :: x(3, n), v(3, n), de
        real(dp), intent(in) :: f(3, n), z1(n), z2(n), z3(n), dtfm(:), sig(:), m2(:), c1, half
        real(dp) :: a1, a2, a3, b1, b2, b3, dk(n)
        integer :: i, t
        do i = 1, n
            t = typ(i)
            a1 = v(1, i) + dtfm(t)*f(1, i)
            a2 = v(2, i) + dtfm(t)*f(2, i)
            a3 = v(3, i) + dtfm(t)*f(3, i)
            b1 = c1*a1 + sig(t)*z1(i)
            b2 = c1*a2 + sig(t)*z2(i)
            b3 = c1*a3 + sig(t)*z3(i)
            x(1, i) = x(1, i) + half*a1 + half*b1
            x(2, i) = x(2, i) + half*a2 + half*b2
            x(3, i) = x(3, i) + half*a3 + half*b3
            v(1, i) = b1; v(2, i) = b2; v(3, i) = b3
            dk(i) = m2(t)*((b1*b1 + b2*b2 + b3*b3) - (a1*a1 + a2*a2 + a3*a3))
        end do
        do i = 1, n
            de = de + dk(i)
        end do
    end subroutine baoab_batch

    !> Global kinetic energy (collective). One type (the common case): m sum v^2 over the contiguous
    !> velocities, a loop that vectorises; otherwise the sum of m v^2 that kinetic_energy takes.
    real(dp) function total_ke(self, atoms) result(ke)
        type(thermostat_t), intent(in) :: self
        type(atoms_t), intent(in) :: atoms
        integer :: i
        real(dp) :: acc
        if (.not. atoms%per_atom_mass .and. atoms%ntypes == 1) then
            acc = 0
            do i = 1, atoms%nlocal
                acc = acc + (atoms%v(1, i)**2 + atoms%v(2, i)**2 + atoms%v(3, i)**2)
            end do
            ke = atoms%mass(1)*acc
        else
            ke = local_mv2(atoms)
        end if
        call sum_all(ke)
        ke = 0.5_dp*self%mvv2e*ke
    end function total_ke

    subroutine scale_velocities(atoms, alpha)
        type(atoms_t), intent(inout) :: atoms
        real(dp), intent(in) :: alpha
        integer :: i
        do i = 1, atoms%nlocal
            atoms%v(1, i) = alpha*atoms%v(1, i)
            atoms%v(2, i) = alpha*atoms%v(2, i)
            atoms%v(3, i) = alpha*atoms%v(3, i)
        end do
    end subroutine scale_velocities

    !> CSVR over a time span: one global kinetic-energy draw (every rank draws the same numbers,
    !> keyed by `event`, e.g. 2 step + half), then a uniform rescale of the owned velocities.
    !> Collective.
    subroutine ts_csvr(self, atoms, span, event, time)
        class(thermostat_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        real(dp), intent(in) :: span, time
        integer(i8), intent(in) :: event
        real(dp) :: ke, ke_new
        ke = total_ke(self, atoms)
        ke_new = csvr_kinetic_energy(self, ke, span, event, time)
        if (ke > 0) call scale_velocities(atoms, sqrt(ke_new/ke))
        self%ecouple_global = self%ecouple_global + (ke_new - ke)
    end subroutine ts_csvr

    !> Time of the next scheduled CSVR rescaling (energy stepping; huge when none).
    pure real(dp) function ts_rescale_time(self) result(t)
        class(thermostat_t), intent(in) :: self
        t = huge(1.0_dp)
        if (self%interval > 0) t = real(self%n_rescale, dp)*self%interval
    end function ts_rescale_time

    !> The scheduled thermostat action at time t (energy stepping), its draws keyed by the index of
    !> the action (the same on every rank and after a restart): CSVR, Bussi's exact kinetic-energy
    !> propagator over one interval (collective); Andersen (global variant), a fresh
    !> Maxwell-Boltzmann velocity for every atom, keyed by (id, index).
    subroutine ts_rescale(self, atoms, t)
        class(thermostat_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        real(dp), intent(in) :: t
        real(dp) :: vnew(3), m, temp
        integer :: i
        if (self%style == thermostat_csvr) then
            call self%csvr(atoms, self%interval, self%n_rescale, t)
        else
            temp = self%target(t)
            do i = 1, atoms%nlocal
                m = atom_mass(atoms, i)
                vnew = maxwell_velocity(self, atoms%id(i), self%n_rescale, 0, temp, m, stream_andersen_global)
                self%ecouple_local = self%ecouple_local + 0.5_dp*self%mvv2e*m*(sum(vnew**2) - sum(atoms%v(:, i)**2))
                atoms%v(:, i) = vnew
            end do
        end if
        self%n_rescale = self%n_rescale + 1
    end subroutine ts_rescale

    !> Bussi's resampled kinetic energy (see the module header); the exact solution of the
    !> kinetic-energy SDE over `span`.
    real(dp) function csvr_kinetic_energy(self, ke, span, event, time) result(ke_new)
        type(thermostat_t), intent(in) :: self
        real(dp), intent(in) :: ke, span, time
        integer(i8), intent(in) :: event
        type(rng_stream_t) :: s
        real(dp) :: c, kt_target, r1, sn
        integer(i8) :: nf
        nf = nint(self%dof, i8)
        if (nf < 1 .or. ke <= 0) then
            ke_new = ke
            return
        end if
        c = exp(-span/self%damping)
        kt_target = 0.5_dp*nf*self%boltz*self%target(time)
        s = rng_stream(self%seed, stream_csvr, 0_i8, event)
        r1 = s%normal()
        sn = s%chi_square(nf - 1)
        ke_new = ke + (1 - c)*(kt_target*(r1*r1 + sn)/nf - ke) + 2*r1*sqrt(c*(1 - c)*ke*kt_target/nf)
        ke_new = max(ke_new, 0.0_dp)
    end function csvr_kinetic_energy

    !> Nose-Hoover chain over a time span (a half step of the integrator): the Trotter
    !> factorisation of exp(iL_NHC span), three Suzuki-Yoshida sub-steps. Collective (one sum).
    subroutine ts_nose_hoover(self, atoms, span, time)
        class(thermostat_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        real(dp), intent(in) :: span, time
        real(dp) :: ke, ke0, kt, q(self%chain_length), g(self%chain_length), w(3), d, scale, total_scale, e
        integer :: m, j, k
        m = self%chain_length
        ke = total_ke(self, atoms)
        ke0 = ke
        if (self%dof <= 0) return
        kt = self%boltz*self%target(time)
        q = kt*self%damping**2
        q(1) = self%dof*q(1)
        w(1) = 1/(2 - 2**(1.0_dp/3)); w(3) = w(1); w(2) = 1 - 2*w(1)
        total_scale = 1
        do k = 1, 3
            d = w(k)*span
            call chain_forces()
            self%v_eta(m) = self%v_eta(m) + 0.5_dp*d*g(m)
            do j = m - 1, 1, -1
                e = exp(-0.25_dp*d*self%v_eta(j + 1))
                self%v_eta(j) = (self%v_eta(j)*e + 0.5_dp*d*g(j))*e
            end do
            scale = exp(-d*self%v_eta(1))
            total_scale = total_scale*scale
            ke = ke*scale*scale
            self%eta = self%eta + d*self%v_eta
            g(1) = (2*ke - self%dof*kt)/q(1)
            do j = 1, m - 1
                e = exp(-0.25_dp*d*self%v_eta(j + 1))
                self%v_eta(j) = (self%v_eta(j)*e + 0.5_dp*d*g(j))*e
                g(j + 1) = (q(j)*self%v_eta(j)**2 - kt)/q(j + 1)
            end do
            self%v_eta(m) = self%v_eta(m) + 0.5_dp*d*g(m)
        end do
        call scale_velocities(atoms, total_scale)
        self%ecouple_global = self%ecouple_global + (ke - ke0)
    contains
        subroutine chain_forces()
            integer :: jj
            g(1) = (2*ke - self%dof*kt)/q(1)
            do jj = 2, m
                g(jj) = (q(jj - 1)*self%v_eta(jj - 1)**2 - kt)/q(jj)
            end do
        end subroutine chain_forces
    end subroutine ts_nose_hoover

    !> Energy held by the chain, sum Q_j v_j^2/2 + Nf kT eta_1 + kT sum_{j>1} eta_j, at time t (for
    !> the extended-energy check of a constant-temperature run).
    pure real(dp) function ts_chain_energy(self, time) result(e)
        class(thermostat_t), intent(in) :: self
        real(dp), intent(in) :: time
        real(dp) :: kt, q
        integer :: j
        e = 0
        if (self%style /= thermostat_nose_hoover) return
        kt = self%boltz*self%target(time)
        do j = 1, self%chain_length
            q = kt*self%damping**2
            if (j == 1) q = self%dof*q
            e = e + 0.5_dp*q*self%v_eta(j)**2
            if (j == 1) then
                e = e + self%dof*kt*self%eta(j)
            else
                e = e + kt*self%eta(j)
            end if
        end do
    end function ts_chain_energy

    !> Maxwell-Boltzmann velocity at temperature temp for mass m (dimension 2: vz = 0), from one
    !> block keyed by (seed, stream, id, event, sub); stream: the Andersen velocity stream unless
    !> given.
    function maxwell_velocity(self, id, event, sub, temp, m, stream) result(v)
        type(thermostat_t), intent(in) :: self
        integer(i8), intent(in) :: id, event
        integer, intent(in) :: sub
        real(dp), intent(in) :: temp, m
        integer, intent(in), optional :: stream
        real(dp) :: v(3), u(4), z(4)
        integer :: st
        st = stream_andersen_velocity
        if (present(stream)) st = stream
        u = unit_from_word(rng_block(self%seed, st, id, event, sub))
        call box_muller(u(1), u(2), z(1), z(2))
        call box_muller(u(3), u(4), z(3), z(4))
        v = sqrt(self%boltz*temp/(m*self%mvv2e))*z(1:3)
        if (self%dimension == 2) v(3) = 0
    end function maxwell_velocity

    !> Andersen for a fixed step (velocity Verlet): atom i collides in step n when its Poisson process
    !> of collision times (andersen_next_collision: rate 1/damping, a function of (seed, id, time)
    !> alone) has a point in ((n - 1) dt, n dt], which happens with probability 1 - exp(-dt/damping);
    !> it then gets a fresh Maxwell-Boltzmann velocity keyed by (seed, id, n). The first point after
    !> the last step looked at is kept in atoms%clock, which travels with the atom (reordering,
    !> migration): a step only compares each atom's clock with n dt and draws for the colliding
    !> atoms (about N dt/damping), instead of one decision per atom per step. A clock not set (the
    !> start of a run, a restart, atoms made afresh) is the first point after (n - 1) dt, the value
    !> the uninterrupted run holds there: nothing goes into a checkpoint, and a restart continues
    !> bitwise.
    subroutine ts_andersen_step(self, atoms, dt, step, time)
        class(thermostat_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        real(dp), intent(in) :: dt, time
        integer(i8), intent(in) :: step
        real(dp) :: temp, vnew(3), de, m, t_now, t_prev, t_next
        integer(i8) :: slot
        integer :: i, index
        call atoms%enable_clock()
        t_now = real(step, dp)*dt
        t_prev = real(step - 1, dp)*dt
        temp = self%target(time)
        de = 0
        do i = 1, atoms%nlocal
            if (atoms%clock(i) > t_now) cycle
            if (atoms%clock(i) == clock_unset) then
                call andersen_next_collision(self%seed, self%damping, atoms%id(i), t_prev, atoms%clock(i), slot, index)
                if (atoms%clock(i) > t_now) cycle
            end if
            m = atom_mass(atoms, i)
            vnew = maxwell_velocity(self, atoms%id(i), step, 0, temp, m)
            de = de + 0.5_dp*self%mvv2e*m*(sum(vnew**2) - sum(atoms%v(:, i)**2))
            atoms%v(:, i) = vnew
            call andersen_next_collision(self%seed, self%damping, atoms%id(i), t_now, t_next, slot, index)
            atoms%clock(i) = t_next
        end do
        self%ecouple_local = self%ecouple_local + de
    end subroutine ts_andersen_step

    !> Remove the total momentum (collective); its kinetic energy P^2/2M goes to ecouple.
    subroutine ts_remove_momentum(self, atoms)
        class(thermostat_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        real(dp) :: p(4), vc(3)
        integer :: i
        p = momentum_and_mass(atoms)
        if (p(4) <= 0) return
        vc = p(1:3)/p(4)
        do i = 1, atoms%nlocal
            atoms%v(:, i) = atoms%v(:, i) - vc
        end do
        self%ecouple_global = self%ecouple_global - 0.5_dp*self%mvv2e*sum(p(1:3)*vc)
    end subroutine ts_remove_momentum

    !> The energy put in so far (collective: folds every rank's partial sum into the global value).
    real(dp) function ts_ecouple(self) result(e)
        class(thermostat_t), intent(inout) :: self
        call self%fold()
        e = self%ecouple_global
    end function ts_ecouple

    !> Fold every rank's partial sum of ecouple into the global value (collective).
    subroutine ts_fold(self)
        class(thermostat_t), intent(inout) :: self
        real(dp) :: part
        part = self%ecouple_local
        call sum_all(part)
        self%ecouple_global = self%ecouple_global + part
        self%ecouple_local = 0
    end subroutine ts_fold

    ! ------------------------------------------------------------------ Andersen, energy stepping

    !> The first collision of atom `id` strictly after time t: its time, slot and index within the
    !> slot (see the module header): a function of its arguments only, the same on every rank,
    !> before and after a restart.
    subroutine andersen_next_collision(seed, damping, id, t, t_next, slot, index)
        integer(i8), intent(in) :: seed, id
        real(dp), intent(in) :: damping, t
        real(dp), intent(out) :: t_next
        integer(i8), intent(out) :: slot
        integer, intent(out) :: index
        type(rng_stream_t) :: s
        real(dp) :: frac, start
        integer :: j
        slot = max(0_i8, int(floor(t/damping), i8))
        do
            s = rng_stream(seed, stream_andersen_time, id, slot)
            start = real(slot, dp)*damping
            frac = 0
            j = 0
            do
                frac = frac + s%exponential()
                if (frac >= 1) exit
                j = j + 1
                t_next = start + frac*damping
                if (t_next > t) then
                    index = j
                    return
                end if
            end do
            slot = slot + 1
        end do
    end subroutine andersen_next_collision

    !> Next collision time of every owned atom after time t (after a list build or a restart: the
    !> atoms were reordered or moved between ranks).
    subroutine ts_andersen_schedule(self, atoms, t)
        class(thermostat_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        real(dp), intent(in) :: t
        integer :: i, n
        n = atoms%nlocal
        if (allocated(self%next_collision)) then
            if (size(self%next_collision) < n) deallocate (self%next_collision, self%collision_slot, self%collision_index)
        end if
        if (.not. allocated(self%next_collision)) &
            allocate (self%next_collision(max(n, 16) + n/4), self%collision_slot(max(n, 16) + n/4), &
                      self%collision_index(max(n, 16) + n/4))
        do i = 1, n
            call andersen_next_collision(self%seed, self%damping, atoms%id(i), t, self%next_collision(i), &
                                         self%collision_slot(i), self%collision_index(i))
        end do
    end subroutine ts_andersen_schedule

    !> Earliest collision time of this rank's atoms (huge when none).
    real(dp) function ts_andersen_first(self, atoms) result(t)
        class(thermostat_t), intent(in) :: self
        type(atoms_t), intent(in) :: atoms
        t = huge(1.0_dp)
        if (atoms%nlocal > 0) t = minval(self%next_collision(1:atoms%nlocal))
    end function ts_andersen_first

    !> Collisions at time t (the global minimum of the collision times): every owned atom whose
    !> collision time is t gets a fresh Maxwell-Boltzmann velocity at the target temperature, keyed by
    !> (id, slot, index), and its next collision time. Returns the number of atoms changed here.
    integer function ts_andersen_collide(self, atoms, t) result(changed)
        class(thermostat_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        real(dp), intent(in) :: t
        real(dp) :: vnew(3), m, temp
        integer :: i
        changed = 0
        temp = self%target(t)
        do i = 1, atoms%nlocal
            if (self%next_collision(i) > t) cycle
            m = atom_mass(atoms, i)
            vnew = maxwell_velocity(self, atoms%id(i), self%collision_slot(i), self%collision_index(i), temp, m)
            self%ecouple_local = self%ecouple_local + 0.5_dp*self%mvv2e*m*(sum(vnew**2) - sum(atoms%v(:, i)**2))
            atoms%v(:, i) = vnew
            call andersen_next_collision(self%seed, self%damping, atoms%id(i), t, self%next_collision(i), &
                                         self%collision_slot(i), self%collision_index(i))
            changed = changed + 1
        end do
    end function ts_andersen_collide

end module terrace_thermostat
