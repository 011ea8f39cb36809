!> The isotropic Martyna-Tobias-Klein barostat in the time-reversible Trotter splitting of
!> Tuckerman, Alejandre, Lopez-Rendon, Jochim & Martyna (J. Phys. A 39, 5629 (2006)), the scheme of
!> LAMMPS fix npt. With eps = ln(V/V0)/d and its velocity v_eps (p_eps = W v_eps):
!>   dr/dt = v + v_eps r,   dv/dt = F/m - alpha v_eps v - (particle chain),   dV/dt = d V v_eps,
!>   dv_eps/dt = G_eps - v_xi'1 v_eps,   G_eps = (alpha 2K + W_vir - d V P0) / W,   alpha = 1 + d/Nf,
!> W = (Nf + d) k T tau_p^2 (tau_p: `damping`; the same mass as LAMMPS's Pdamp: d (N+1) k T Pdamp^2
!> over d strains), the barostat's own Nose-Hoover chain (three links, Q = k T tau_p^2) on v_eps,
!> the particles' chain the run's &thermostat style = 'nose_hoover'. One velocity Verlet step:
!>   [barostat chain dt/2] [particle chain dt/2] v_eps += dt/2 G_eps
!>   v <- v e^(-alpha v_eps h) + h F/m e^(-alpha v_eps h/2) sinhc(alpha v_eps h/2)        (h = dt/2)
!>   x <- x e^(v_eps dt) + dt v e^(v_eps dt/2) sinhc(v_eps dt/2),  box edges * e^(v_eps dt)
!>   forces;  the same kick;  v_eps += dt/2 G_eps;  [particle chain dt/2] [barostat chain dt/2]
!> The two chains act on different variables and commute, so the step is its own reverse. The
!> conserved quantity is K + U + P0 V + W v_eps^2/2 + (barostat chain's energy) + (particle
!> chain's energy); the particle chain's is booked by the thermostat as ecouple, the rest here
!> (energy). The barostat is deterministic: every rank holds the same v_eps and chain from global
!> sums, and a checkpoint holds them and the last virial.
!>
!> couple = 'aniso' (the diagonal MTK of Shinoda, Shiga & Mikami, Phys. Rev. B 69, 134103 (2004), as
!> LAMMPS fix npt aniso): a strain rate nu_a per edge (v_axis), dL_a/dt = nu_a L_a, each of mass
!> W_a = (Nf + d)/d k T tau_p^2 (LAMMPS: (N+1) k T Pdamp^2),
!>   dr_a/dt = v_a + nu_a r_a,   dv_a/dt = F_a/m - (nu_a + sum_b nu_b / Nf) v_a - (particle chain),
!>   dnu_a/dt = G_a - v_xi'1 nu_a,   G_a = (2 K_aa + W_aa - V P0 + 2 K / Nf) / W_a,
!> (W_aa the virial's diagonal), the same splitting edge by edge: the kick's rate and the drift's
!> scale per axis; the barostat chain driven by sum_a W_a nu_a^2 - d k T (its first link's energy
!> d k T eta_1). Conserved: K + U + P0 V + sum_a W_a nu_a^2/2 + the chains' energies.
module terrace_barostat_mttk
    use terrace_kinds, only: dp, i8
    use terrace_engine, only: engine_t
    use terrace_velocities, only: kinetic_energy
    use terrace_barostat, only: barostat_t, barostat_params_t, kinetic_diagonal, exchange_reals, exchange_iso_aniso
    use terrace_named_values, only: named_values_t
    implicit none
    private

    integer, parameter :: chain_length = 3

    type, extends(barostat_t), public :: mttk_t
        real(dp) :: w = 1                        !< the barostat's mass W
        real(dp) :: q = 1                        !< the chain's masses
        real(dp) :: alpha = 1                    !< 1 + d/Nf
        real(dp) :: v_eps = 0
        real(dp) :: eta(chain_length) = 0, v_eta(chain_length) = 0
        real(dp) :: virial = 0                   !< the virial at the present positions
        logical :: have_virial = .false.
        real(dp) :: mu(3) = 1                    !< this step's box scale, applied by before_forces
        !> aniso: each edge's strain rate, its mass, the virial's diagonal at the present positions
        real(dp) :: v_axis(3) = 0, w_axis = 1, virial_axis(3) = 0
        real(dp) :: nf = 1                       !< the particles' degrees of freedom d N - d
    contains
        procedure :: setup => mttk_setup
        procedure :: retarget => mttk_masses
        procedure :: replaces_kicks => mttk_replaces_kicks
        procedure :: first_half => mttk_first_half
        procedure :: before_forces => mttk_before_forces
        procedure :: second_half => mttk_second_half
        procedure :: after_step => mttk_after_step
        procedure :: energy => mttk_energy
        procedure :: exchange_own => mttk_exchange
    end type mttk_t

contains

    subroutine mttk_setup(self, p)
        class(mttk_t), intent(inout) :: self
        type(barostat_params_t), intent(in) :: p
        real(dp) :: nf
        nf = max(real(p%dimension, dp)*real(p%natoms, dp) - p%dimension, 1.0_dp)
        self%alpha = 1 + p%dimension/nf
        self%nf = nf
        call mttk_masses(self)
        self%v_eps = 0; self%eta = 0; self%v_eta = 0; self%v_axis = 0
        self%have_virial = .false.
    end subroutine mttk_setup

    !> The barostat's masses from k T (again when a temperature ramp moves it: the same frequencies).
    subroutine mttk_masses(self)
        class(mttk_t), intent(inout) :: self
        self%w = (self%nf + self%p%dimension)*self%kt*self%tau**2
        self%q = self%kt*self%tau**2
        self%w_axis = self%w/self%p%dimension
    end subroutine mttk_masses

    logical function mttk_replaces_kicks(self)
        class(mttk_t), intent(in) :: self
        mttk_replaces_kicks = .true.
    end function mttk_replaces_kicks

    !> The barostat's chain dt/2, v_eps dt/2, the scaled half kick and the drift (the box and the
    !> positions' scaling by e^(v_eps dt) left to before_forces). Collective.
    subroutine mttk_first_half(self, eng, dtfm, dtf, dt, step)
        class(mttk_t), intent(inout) :: self
        type(engine_t), intent(inout) :: eng
        real(dp), intent(in) :: dtfm(:), dtf, dt
        integer(i8), intent(in) :: step
        real(dp) :: c(3), rate(3)
        integer :: a
        if (.not. self%have_virial) then         ! the first step: the initial force pass's virial
            self%virial = eng%virial
            self%virial_axis = eng%virial_diag
            self%have_virial = .true.
        end if
        call chain(self, 0.5_dp*dt)
        call push(self, eng, 0.5_dp*dt)
        call scaled_kick(self, eng, dtfm, dtf, dt)
        ! x e^(v_eps dt) + dt v e^(v_eps dt/2) sinhc(v_eps dt/2) = e^(v_eps dt) (x + c v), per axis
        rate = self%v_eps
        if (self%p%aniso) rate = self%v_axis
        do a = 1, 3
            self%mu(a) = merge(exp(rate(a)*dt), 1.0_dp, a <= self%p%dimension)
            c(a) = dt*exp(-0.5_dp*rate(a)*dt)*sinhc(0.5_dp*rate(a)*dt)
        end do
        call drift(eng%atoms%nlocal, eng%atoms%x, eng%atoms%v, c)
    end subroutine mttk_first_half

    !> The box and the positions scaled by this step's e^(v_eps dt) (the list kept while the skin
    !> test allows: moved only when it was rebuilt here).
    subroutine mttk_before_forces(self, eng, step, moved)
        class(mttk_t), intent(inout) :: self
        include 'barostat_hook_args.inc'
        call eng%scale_box(self%mu, velocities=.false., keep_list=.true., rebuilt=moved)
    end subroutine mttk_before_forces

    !> The scaled half kick with the new forces, then v_eps dt/2 with the new virial. Collective.
    subroutine mttk_second_half(self, eng, dtfm, dtf, dt, step)
        class(mttk_t), intent(inout) :: self
        type(engine_t), intent(inout) :: eng
        real(dp), intent(in) :: dtfm(:), dtf, dt
        integer(i8), intent(in) :: step
        call scaled_kick(self, eng, dtfm, dtf, dt)
        self%virial = eng%virial
        self%virial_axis = eng%virial_diag
        call push(self, eng, 0.5_dp*dt)
    end subroutine mttk_second_half

    !> The barostat's chain dt/2 (after the particles' chain).
    subroutine mttk_after_step(self, eng, step, moved)
        class(mttk_t), intent(inout) :: self
        include 'barostat_hook_args.inc'
        moved = .false.
        call chain(self, 0.5_dp*self%p%dt)
    end subroutine mttk_after_step

    !> v_eps += span G_eps, G_eps = (alpha 2K + W_vir - d V P0)/W (collective: the kinetic energy);
    !> aniso: nu_a += span G_a, G_a = (2 K_aa + W_aa - V P0 + 2 K / Nf) / W_a.
    subroutine push(self, eng, span)
        class(mttk_t), intent(inout) :: self
        type(engine_t), intent(inout) :: eng
        real(dp), intent(in) :: span
        real(dp) :: ke, kd(3), v
        integer :: d
        if (self%p%aniso) then
            d = self%p%dimension
            kd = kinetic_diagonal(eng)
            v = eng%box%volume()
            self%v_axis(1:d) = self%v_axis(1:d) + span*(2*kd(1:d) + self%virial_axis(1:d) - v*self%p0 + &
                                                        2*sum(kd)/self%nf)/self%w_axis
            return
        end if
        ke = kinetic_energy(eng%atoms, eng%units)
        self%v_eps = self%v_eps + span*(self%alpha*2*ke + self%virial - &
                                        self%p%dimension*eng%box%volume()*self%p0)/self%w
    end subroutine push

    !> The barostat's Nose-Hoover chain over a span: three Suzuki-Yoshida sub-steps of the Trotter
    !> factorisation, the chain's first link driven by W v_eps^2 - k T (one degree of freedom; aniso:
    !> sum_a W_a nu_a^2 - d k T).
    subroutine chain(self, span)
        class(mttk_t), intent(inout) :: self
        real(dp), intent(in) :: span
        real(dp) :: w(3), d, e, g(chain_length), ke2, lkt
        integer :: k, j, m
        m = chain_length
        w(1) = 1/(2 - 2**(1.0_dp/3)); w(3) = w(1); w(2) = 1 - 2*w(1)
        lkt = self%kt
        if (self%p%aniso) lkt = self%p%dimension*self%kt
        do k = 1, 3
            d = w(k)*span
            ke2 = barostat_ke2(self)
            g(1) = (ke2 - lkt)/self%q
            do j = 2, m
                g(j) = (self%q*self%v_eta(j - 1)**2 - self%kt)/self%q
            end do
            self%v_eta(m) = self%v_eta(m) + 0.5_dp*d*g(m)
            do j = m - 1, 1, -1
                e = exp(-0.25_dp*d*self%v_eta(j + 1))
                self%v_eta(j) = (self%v_eta(j)*e + 0.5_dp*d*g(j))*e
            end do
            self%v_eps = self%v_eps*exp(-d*self%v_eta(1))
            self%v_axis = self%v_axis*exp(-d*self%v_eta(1))
            self%eta = self%eta + d*self%v_eta
            g(1) = (barostat_ke2(self) - lkt)/self%q
            do j = 1, m - 1
                e = exp(-0.25_dp*d*self%v_eta(j + 1))
                self%v_eta(j) = (self%v_eta(j)*e + 0.5_dp*d*g(j))*e
                g(j + 1) = (self%q*self%v_eta(j)**2 - self%kt)/self%q
            end do
            self%v_eta(m) = self%v_eta(m) + 0.5_dp*d*g(m)
        end do
    end subroutine chain

    !> Twice the barostat's kinetic energy: W v_eps^2 (aniso: sum_a W_a nu_a^2).
    pure real(dp) function barostat_ke2(self) result(ke2)
        class(mttk_t), intent(in) :: self
        if (self%p%aniso) then
            ke2 = self%w_axis*sum(self%v_axis**2)
        else
            ke2 = self%w*self%v_eps**2
        end if
    end function barostat_ke2

    !> The barostat's own energy: W v_eps^2/2 + its chain's sum Q v_j^2/2 + k T eta_j (aniso: the
    !> first link's d k T eta_1).
    real(dp) function mttk_energy(self, eng)
        class(mttk_t), intent(in) :: self
        type(engine_t), intent(in) :: eng
        mttk_energy = 0.5_dp*barostat_ke2(self) + sum(0.5_dp*self%q*self%v_eta**2 + self%kt*self%eta)
        if (self%p%aniso) mttk_energy = mttk_energy + (self%p%dimension - 1)*self%kt*self%eta(1)
    end function mttk_energy

    !> v <- v e^(-alpha v_eps h) + h F/m e^(-alpha v_eps h/2) sinhc(alpha v_eps h/2), h = dt/2
    !> (dtfm(type) = h ftm2v/m, or dtf/rmass); aniso: per axis, the rate nu_a + sum_b nu_b / Nf.
    subroutine scaled_kick(self, eng, dtfm, dtf, dt)
        class(mttk_t), intent(in) :: self
        type(engine_t), intent(inout) :: eng
        real(dp), intent(in) :: dtfm(:), dtf, dt
        real(dp) :: a(3), s_v(3), s_f(3)
        integer :: k
        if (self%p%aniso) then
            a = (self%v_axis + sum(self%v_axis)/self%nf)*0.5_dp*dt
        else
            a = self%alpha*self%v_eps*0.5_dp*dt
        end if
        s_v = exp(-a)
        do k = 1, 3
            s_f(k) = exp(-0.5_dp*a(k))*sinhc(0.5_dp*a(k))
        end do
        if (eng%atoms%per_atom_mass) then
            call kick_masses(eng%atoms%nlocal, eng%atoms%v, eng%atoms%f, eng%atoms%rmass, dtf, s_v, s_f)
        else
            call kick_types(eng%atoms%nlocal, eng%atoms%v, eng%atoms%f, eng%atoms%type, dtfm, s_v, s_f)
        end if
    end subroutine scaled_kick

    subroutine kick_types(n, v, f, type, dtfm, s_v, s_f)
        integer, intent(in) :: n, type(n)
        real(dp), intent(inout) :: v(3, n)
        real(dp), intent(in) :: f(3, n), dtfm(:), s_v(3), s_f(3)
        integer :: i
        do i = 1, n
            v(:, i) = s_v*v(:, i) + (s_f*dtfm(type(i)))*f(:, i)
        end do
    end subroutine kick_types

    subroutine kick_masses(n, v, f, rmass, dtf, s_v, s_f)
        integer, intent(in) :: n
        real(dp), intent(inout) :: v(3, n)
        real(dp), intent(in) :: f(3, n), rmass(n), dtf, s_v(3), s_f(3)
        integer :: i
        do i = 1, n
            v(:, i) = s_v*v(:, i) + (s_f*dtf/rmass(i))*f(:, i)
        end do
    end subroutine kick_masses

    subroutine drift(n, x, v, c)
        integer, intent(in) :: n
        real(dp), intent(inout) :: x(3, n)
        real(dp), intent(in) :: v(3, n), c(3)
        integer :: i
        do i = 1, n
            x(:, i) = x(:, i) + c*v(:, i)
        end do
    end subroutine drift

    !> sinh(z)/z, by its series near 0 (to round-off for |z| < 1e-3).
    pure real(dp) function sinhc(z)
        real(dp), intent(in) :: z
        if (abs(z) < 1.0e-3_dp) then
            sinhc = 1 + z*z/6*(1 + z*z/20)
        else
            sinhc = sinh(z)/z
        end if
    end function sinhc

    !> The strain rate (aniso: each edge's), the virial at the present positions and the chain.
    subroutine mttk_exchange(self, values, saving, ok)
        class(mttk_t), intent(inout) :: self
        include 'checkpointed_args.inc'
        call exchange_iso_aniso(values, self%p%aniso, 'baro_v_eps', self%v_eps, 'baro_v_axis_', self%v_axis, saving, ok)
        call exchange_iso_aniso(values, self%p%aniso, 'baro_virial', self%virial, 'baro_virial_axis_', self%virial_axis, &
                                saving, ok)
        if (.not. saving) self%have_virial = .true.
        call exchange_reals(values, 'baro_eta_', self%eta(1:chain_length), saving, ok)
        call exchange_reals(values, 'baro_v_eta_', self%v_eta(1:chain_length), saving, ok)
    end subroutine mttk_exchange

end module terrace_barostat_mttk
